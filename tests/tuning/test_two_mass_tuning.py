"""Tuning and Monte Carlo over a compliant shaft's spread (the servo-two-mass preset): the shaft tolerances
become batch plant factors and study parameters, the filters are tuned with the speed PI, and a small
robust tuning improves the held-out cost with every drawn plant stable (benchmarks/two_mass_tuning.py is
the full-size run)."""

import json

import numpy as np
import pytest

from pmsmjax.io.drive_files import PRESET_FOLDER, drive_spec
from tuning.autotune import drive_scaling
from tuning.autotune.job import speed_filter_names
from tuning.autotune.scenario_batches import make_batch
from tuning.montecarlo import study as mc_study
from tuning.montecarlo.distributions import sample

SERVO = (PRESET_FOLDER / "servo_two_mass.toml").read_text()
NOTCH = (
    "[control]\nspeed_filter_hz = 1000.0\nnotch_hz = 200.0\nnotch_width_hz = 100.0\nnotch_depth_db = 20.0\n"
)


@pytest.fixture(scope="module")
def notch_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("servo") / "notch.toml"
    path.write_text(SERVO.replace("[control]\n", NOTCH))
    return str(path)


def test_shaft_tolerances_are_drawn(notch_file):
    spec = drive_spec(notch_file)
    spread = drive_scaling.plant_spread(spec)
    assert spread["shaft_stiffness"] == 0.4 and spread["load_inertia"] == 0.1
    batch = make_batch(64, 0, duration_s=(0.01, 0.01), plant_spread=spread, Ts=spec.Ts)
    k = np.asarray(batch.plant_scale["shaft_stiffness"])
    assert 0.6 <= k.min() < 0.7 and 1.3 < k.max() <= 1.4  # the resonance moves by sqrt(0.6..1.4): +-20 %
    assert speed_filter_names(spec) == tuple(
        f"controller.speed.filters.{k}"
        for k in ("speed_filter_hz", "notch_hz", "notch_width_hz", "notch_depth_db")
    )
    study = mc_study.Study(motor=notch_file, n=32, duration_s=0.01, load_time_s=0.005)
    assert study.parameters["motor.shaft_stiffness"]["tolerance"] == 0.4
    drive = mc_study.build_drive(study)
    drawn = sample(mc_study.distributions(study, drive), 32, 0)
    np.testing.assert_array_less(np.abs(drawn["motor.shaft_stiffness"] / 52.6 - 1.0), 0.4 + 1e-9)


@pytest.mark.slow
def test_small_robust_tuning_of_the_notch(notch_file, tmp_path):
    from pmsmjax.cli import main as pmsmjax

    out = tmp_path / "tune"
    argv = ["tune", "--motor", notch_file, "--robust", "--train", "4", "--heldout", "4", "--iterations", "4"]
    assert pmsmjax([*argv, "--no-progress", "--out", str(out)]) == 0
    result = json.loads((out / "result.json").read_text())
    assert "controller.speed.filters.notch_hz" in result["gains"]["after"]
    assert result["heldout"]["after"]["cost"] <= result["heldout"]["before"]["cost"]
    mc = tmp_path / "mc"
    argv = ["montecarlo", "--motor", notch_file, "--n", "16", "--gains", str(out / "gains.toml")]
    assert pmsmjax([*argv, "--out", str(mc), "--no-figures", "--no-progress", "--sensitivity-runs", "0"]) == 0
    failures = json.loads((mc / "summary.json").read_text())["failures"]
    assert failures["unstable"]["count"] == 0 and failures["any"]["count"] == 0
