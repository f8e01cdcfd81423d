"""``compare`` and ``tune`` on the preset saturated-ipm drive file, whose FOC controls on its flux map
(pmsmjax/presets/flux_map_control.py): the comparison holds the rated speed under 0.8 x the map's rated
torque inside the current limit, and a short tune starts from the internal-model gains of the file's
bandwidth and linear model and differentiates through the scheduled current loop and the map's loci;
the observer comparison, which runs the book drive on a file's constants, refuses a map file."""

import json
import math

import pytest

from pmsmjax.cli import main
from pmsmjax.io.drive_files import drive_spec
from tuning.parameters import read_gains_toml


@pytest.mark.slow
def test_compare_on_the_flux_map_drive(tmp_path):
    spec = drive_spec("saturated-ipm")
    out = tmp_path / "cmp"
    assert (
        main(["compare", "--motor", "saturated-ipm", "--control", "pi", "--no-figures", "--out", str(out)])
        == 0
    )
    pi = json.loads((out / "compare.json").read_text())["controllers"]["pi"]
    rated = spec.ratings["rated_speed_rpm"]
    assert abs(pi["final_speed_rpm"] - rated) <= 0.005 * rated
    assert pi["peak_current_a"] <= spec.ratings["max_current_a"] * (1 + 1e-6)
    load = 0.8 * spec.ratings["rated_torque_nm"] + spec.motor["B"] * rated * math.pi / 30.0
    assert pi["mean_torque_nm"] == pytest.approx(load, rel=0.01)  # the steady state's torque balance
    assert pi["operating_point"]["flags"] == [] and pi["operating_point"]["ok"]


def test_the_observer_comparison_refuses_to_stand_in_a_linear_model_for_the_map(tmp_path, capsys):
    # compare --estimator runs the book drive on the file's constants: on a map file that would compare
    # the observers on the map's linear model, not on the saturated machine (demo runs the map)
    out = tmp_path / "cmp"
    for estimator in ("smo", "hfi-pulsating"):
        argv = ["compare", "--motor", "saturated-ipm", "--estimator", estimator, "--out", str(out)]
        assert main(argv) == 2
        message = capsys.readouterr().err.strip().splitlines()
        assert len(message) == 1 and "pmsmjax demo --motor FILE --estimator NAME" in message[0]
    assert not out.exists()


@pytest.mark.slow
def test_tune_on_the_flux_map_drive(tmp_path):
    spec = drive_spec("saturated-ipm")
    out = tmp_path / "tune"
    argv = ["tune", "--motor", "saturated-ipm", "--out", out, "--train", "2", "--heldout", "2"]
    argv += ["--iterations", "2", "--eval-substeps", "1", "--duration-s", "0.03", "0.04", "--no-progress"]
    assert main([str(a) for a in argv]) == 0
    data = json.loads((out / "result.json").read_text())
    before = data["gains"]["before"]
    a_c = spec.control["current_bandwidth_rad_s"]
    assert before["controller.current.kp_d"] == pytest.approx(a_c * spec.motor["L_d"], rel=1e-6)
    assert before["controller.current.kp_q"] == pytest.approx(a_c * spec.motor["L_q"], rel=1e-6)
    assert before["controller.current.ki_q"] == pytest.approx(a_c * spec.motor["R"], rel=1e-6)
    after = read_gains_toml(out / "gains.toml")
    assert after == pytest.approx(data["gains"]["after"], rel=1e-12)
    # the gradient through the map's loci and scheduled loop is finite, and the kept gains no worse
    assert all(math.isfinite(c) for c in data["cost_history"])
    assert data["train"]["after"]["cost"] <= data["train"]["before"]["cost"]
