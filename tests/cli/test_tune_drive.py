"""``pmsmjax tune --motor FILE``: the user's drive file tuned (plainly and robustly), its flags, and the
refusals a careless user gets (one line, exit 2, nothing written)."""

import json
import shutil

import numpy as np
import pytest

from pmsmjax.cli import main
from pmsmjax.io.drive_files import PRESET_FILES, PRESET_FOLDER
from tuning.parameters import read_gains_toml

BOOK_MOTOR_ONLY = """R = 0.958
L_d = 0.00525
L_q = 0.00525
psi_f = 0.1827
pole_pairs = 4
J = 0.003
B = 0.008
"""


def refused(capsys, argv, *needles, out):
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err
    assert "Traceback" not in err
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    assert not out.exists()


@pytest.mark.slow
def test_robust_tune_on_a_drive_file(tmp_path, capsys):
    """A few iterations on a tiny batch of the 400 W servo's file with --robust and --current-limit: the
    outputs name the file; the plant draws lie within its tolerances; the worst decile is the mean of the
    worst tenth of the drawn per-scenario costs (so at least their mean); the limit reached the drive."""
    drive_file = tmp_path / "servo.toml"
    shutil.copy(PRESET_FOLDER / PRESET_FILES["servo-400w"], drive_file)
    out = tmp_path / "tune"
    argv = ["tune", "--motor", drive_file, "--robust", "--current-limit", "30", "--out", out]
    argv += ["--train", "2", "--heldout", "10", "--iterations", "2", "--eval-substeps", "1"]
    assert main([str(a) for a in [*argv, "--duration-s", "0.03", "0.04", "--no-progress"]]) == 0
    printed = capsys.readouterr().out
    assert "held-out cost on the nominal plant" in printed and "worst decile" in printed
    data = json.loads((out / "result.json").read_text())
    assert data["drive_file"]["source"] == str(drive_file) and data["robust"] is True
    assert data["drive_file"]["ratings"]["max_current_a"] == 30.0
    assert read_gains_toml(out / "gains.toml") == pytest.approx(data["gains"]["after"], rel=1e-12)
    r = data["robustness"]
    tolerances = data["drive_file"]["tolerances"]
    assert set(r["plant_scale"]) == set(tolerances) and "u_dc_v" in r["plant_scale"]
    for key, scale in r["plant_scale"].items():
        assert len(scale) == 10 and np.all(np.abs(np.asarray(scale) - 1.0) <= tolerances[key])
    assert data["config"]["plant_spread"] == tolerances  # trained over the same draws' law
    for when in ("before", "after"):
        costs = np.asarray(r["drawn_per_scenario_cost"][when])
        assert r["worst_decile_cost"][when] == pytest.approx(np.sort(costs)[-1:].mean(), rel=1e-12)
        assert r["worst_decile_cost"][when] >= costs.mean()
        assert r["drawn_mean_cost"][when] == pytest.approx(costs.mean(), rel=1e-12)
        assert np.isfinite(r["nominal_cost"][when])
        # the current figures are against the file's limit as overridden: peak - (peak - limit) = 30 A
        for s in data["heldout"][when]["per_scenario"]:
            assert s["peak_current_a"] - s["current_over_limit_a"] == pytest.approx(30.0, rel=1e-9)
    speeds = data["config"]["speed_rpm"]
    assert speeds == [600.0, 3000.0] and data["config"]["Ts"] == pytest.approx(5e-5)


def test_robust_without_tolerances_is_refused(tmp_path, capsys):
    motor = tmp_path / "motor.toml"
    motor.write_text(BOOK_MOTOR_ONLY)
    out = tmp_path / "tune"
    refused(
        capsys,
        ["tune", "--motor", motor, "--robust", "--out", out],
        str(motor),
        "[tolerances]",
        "[operating]",
        out=out,
    )
    config = tmp_path / "job.toml"
    config.write_text("[job]\nrobust = true\n")
    argv = ["tune", "--motor", motor, "--config", config, "--out", out]
    refused(capsys, argv, "[job] robust = true", "[tolerances]", out=out)


@pytest.mark.slow
def test_robust_tune_over_the_operating_range_alone(tmp_path, capsys):
    """A drive file with ``[operating]`` but no ``[tolerances]`` tunes with --robust: the plant draws are
    the winding temperatures of its band and nothing else."""
    motor = tmp_path / "warm.toml"
    motor.write_text(
        f"[motor]\n{BOOK_MOTOR_ONLY}\n[thermal]\nr_th_k_per_w = 0.5\nc_th_j_per_k = 1500.0\n"
        "ambient_c = 20.0\ninitial_c = 20.0\n\n[operating]\nwinding_temperature_c = [20.0, 140.0]\n"
    )
    out = tmp_path / "tune"
    argv = ["tune", "--motor", motor, "--robust", "--out", out, "--train", "2", "--heldout", "4"]
    argv += ["--iterations", "1", "--eval-substeps", "1", "--duration-s", "0.03", "0.04", "--no-progress"]
    assert main([str(a) for a in argv]) == 0
    data = json.loads((out / "result.json").read_text())
    assert data["robust"] is True and set(data["config"]["plant_spread"]) == {"initial_k"}
    start_k = 293.15 * np.asarray(data["robustness"]["plant_scale"]["initial_k"])
    assert np.all((293.15 - 1e-3 <= start_k) & (start_k <= 413.15 + 1e-3)) and np.ptp(start_k) > 10.0


def test_drive_flags_are_checked_before_any_work(tmp_path, capsys):
    out = tmp_path / "tune"
    refused(
        capsys, ["tune", "--motor", "servo-400w", "--u-dc", "0.048", "--out", out], "--u-dc", "kV", out=out
    )
    refused(
        capsys, ["tune", "--motor", "servo_400w", "--out", out], "--motor servo_400w", "servo-400w", out=out
    )
