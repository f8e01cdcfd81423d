"""The commissioning chain a user runs on their own drive, end to end through the command line: a noisy
closed-loop log made without the engine (:mod:`tuning.identify.reference_log`) -> ``identify`` (writes
motor.toml) -> ``tune --robust`` -> ``montecarlo`` -> ``demo`` with the tuned gains, on the 48 V servo
(not the book's motor). Small settings; the full-size chain and its timing are
benchmarks/commissioning_chain.py."""

import json
import math

import pytest

from pmsmjax.cli import main as pmsmjax
from pmsmjax.io.drive_files import drive_spec
from pmsmjax.io.logs import write_csv_atomic
from tuning.identify.reference_log import commissioning_log

DRIVE = "servo-400w"
#: The identify bars of the chain, relative to the true motor.
BARS = {"R": 0.01, "L_d": 0.02, "L_q": 0.02, "psi_f": 0.005, "J": 0.03}


@pytest.mark.slow
def test_log_identify_tune_montecarlo_demo(tmp_path):
    truth = drive_spec(DRIVE)
    write_csv_atomic(tmp_path / "log.csv", commissioning_log(truth, 0.4, 0.005))
    motor = tmp_path / "id" / "motor.toml"
    gains = tmp_path / "tune" / "gains.toml"

    assert pmsmjax(["identify", str(tmp_path / "log.csv"), "--motor", DRIVE, "--out", str(motor.parent)]) == 0
    found = drive_spec(motor)
    for name, bar in BARS.items():
        assert abs(found.motor[name] / truth.motor[name] - 1.0) < bar, name
    params = json.loads((motor.parent / "params.json").read_text())["parameters"]
    for name in BARS:  # the tolerance is the 95 % interval's wider side, relative
        low, high = params[name]["ci95"]
        value = params[name]["value"]
        assert math.isclose(found.tolerances[name], max(high - value, value - low) / value, rel_tol=1e-9)
    assert found.inverter["u_dc_v"] == truth.inverter["u_dc_v"]  # the prior's inverter carried over
    assert found.ratings["max_current_a"] == truth.ratings["max_current_a"]

    tune = ["tune", "--motor", str(motor), "--robust", "--train", "8", "--heldout", "8", "--iterations", "10"]
    assert pmsmjax([*tune, "--out", str(gains.parent), "--no-progress"]) == 0
    result = json.loads((gains.parent / "result.json").read_text())
    assert result["robust"] and result["drive_file"]["source"] == str(motor)
    assert result["heldout"]["after"]["itae"] < result["heldout"]["before"]["itae"]

    mc = [
        "montecarlo",
        "--motor",
        str(motor),
        "--gains",
        str(gains),
        "--n",
        "32",
        "--out",
        str(tmp_path / "mc"),
    ]
    assert pmsmjax([*mc, "--no-progress", "--no-figures"]) == 0
    study = json.loads((tmp_path / "mc" / "summary.json").read_text())
    assert study["n_runs"] == 32 and study["drive_file"]["source"] == str(motor)

    demo = ["demo", "--motor", str(motor), "--gains", str(gains), "--out", str(tmp_path / "demo")]
    assert pmsmjax([*demo, "--no-figures"]) == 0
    summary = json.loads((tmp_path / "demo" / "summary.json").read_text())
    assert summary["drive"]["gains"] == str(gains)
    rated = truth.ratings["rated_speed_rpm"]
    assert abs(summary["metrics"]["final_speed_rpm"] - rated) < 0.005 * rated
    assert summary["metrics"]["peak_phase_current_a"] <= 1.01 * found.current_limit_a
    assert summary["operating_point"]["flags"] == []
