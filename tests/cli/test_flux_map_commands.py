"""``compare`` and ``tune`` on the preset saturated-ipm drive file, whose FOC controls on its flux map
(pmsmjax/presets/flux_map_control.py): the comparison holds the rated speed under 0.8 x the map's rated
torque inside the current limit, and a short tune starts from the internal-model gains of the file's
bandwidth and linear model and differentiates through the scheduled current loop and the map's loci.

``compare --estimator`` on the map file runs the file's own drive with each observer reading the map
(pmsmjax/jobs/estimator_comparison.py): the flux observer, exact on the map, holds the angle within a
fraction of a degree after the hand-over, and the map-aware smo-pll is a different run from the constant
one, which keeps the saturated machine's steady angle error (the active-flux angle of the map with the
constant L_q, pmsmjax/estimators/map_angle_corrected.py, about 16 degrees at the rated point); the
chapter 6 estimators, which run their own salient motor, are refused on a map file."""

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


def test_the_observer_comparison_refuses_what_does_not_run_on_the_map(tmp_path, capsys):
    # HF injection runs on the map within its injection region: the file's 4.94 N m scenario load is beyond
    # saturated-ipm's 3.23 N m; --observer-model means nothing without a map
    out = tmp_path / "cmp"
    for argv, words in (
        (["--motor", "saturated-ipm", "--estimator", "hfi-pulsating"], "[scenario] load_nm = 4.94"),
        (["--motor", "saturated-ipm", "--estimator", "smo,hybrid"], "mixes chapter 5 observers"),
        (["--estimator", "smo", "--observer-model", "constant"], "--observer-model applies to --estimator"),
        (["--motor", "saturated-ipm", "--observer-model", "map"], "--observer-model applies to --estimator"),
    ):
        assert main(["compare", *argv, "--out", str(out)]) == 2
        message = capsys.readouterr().err.strip().splitlines()
        assert len(message) == 1 and words in message[0], message
    assert not out.exists()


# the file's scenario shortened (rated speed, 0.8 x rated torque), the averaged bridge, no sweep
SHORT = dict(load_time_s=0.15, duration_s=0.2, bridge="averaged", window_cycles=2)


def _short_settings(spec):
    from pmsmjax.jobs.control_comparison import ControllerCompareSettings

    s = spec.scenario
    return ControllerCompareSettings(speed_rpm=s["speed_rpm"], load_nm=s["load_nm"], **SHORT)


def test_the_observers_read_the_map_in_the_comparison():
    from pmsmjax.estimators.map_angle_corrected import MapAngleCorrected
    from pmsmjax.jobs.estimator_comparison import compare_estimators, map_observer_drive

    spec = drive_spec("saturated-ipm")
    settings = _short_settings(spec)
    # the drive: the file's map plant and I/f start, the observer inside the map's angle correction
    drive = map_observer_drive(spec, "smo-pll")
    assert type(drive.machine).__name__ == "PMSMFluxMapdq"
    assert isinstance(drive.estimator.observer, MapAngleCorrected)
    assert float(drive.estimator.i_start) == spec.control["startup_current_a"]
    runs = {
        model: compare_estimators(["smo-pll"], None, settings, None, spec=spec, observer_model=model)
        for model in ("map", "constant")
    }
    entry = {m: r["controllers"]["smo-pll"] for m, r in runs.items()}
    assert runs["map"]["settings"]["observer_model"] == "map"
    # figures judged after the file's own hand-over: (47.1 + 31.4) rad/s / 1155.6 rad/s^2 + 23.8 ms
    assert runs["map"]["settings"]["converged_after_s"] == pytest.approx(0.0918, abs=1e-4)
    assert not entry["map"]["lock_lost"] and not entry["constant"]["lock_lost"]
    assert entry["map"]["angle_error_rms_deg"] < 2.0  # the map's correction takes the steady error out
    assert entry["constant"]["angle_error_rms_deg"] > 10.0  # the constant model keeps it
    rated = spec.scenario["speed_rpm"]
    assert abs(entry["map"]["final_speed_rpm"] - rated) < 0.01 * rated


@pytest.mark.slow
def test_compare_estimator_on_the_flux_map_drive(tmp_path):
    spec = drive_spec("saturated-ipm")
    out = tmp_path / "cmp"
    argv = ["compare", "--motor", "saturated-ipm", "--estimator", "flux-observer,smo-pll"]
    assert main([*argv, "--no-figures", "--out", str(out)]) == 0
    data = json.loads((out / "compare.json").read_text())
    table = (out / "compare_estimators.md").read_text()
    assert table.count("\n| flux-observer |") == 1 and table.count("\n| smo-pll |") == 1
    settings = data["settings"]
    assert settings["observer_model"] == "map" and settings["speed_rpm"] == spec.scenario["speed_rpm"]
    # the low-speed sweep on the drive: the file's load, the book's speeds times 3000 / 1000 r/min
    sweep = settings["sweep"]
    assert sweep["load_nm"] == pytest.approx(spec.scenario["load_nm"], rel=1e-12)
    assert sweep["start_rpm"] == 1500.0 and sweep["speeds_rpm"][-1] == pytest.approx(6.0)
    flux, pll = data["estimators"]["flux-observer"], data["estimators"]["smo-pll"]
    # the flux observer on the map it reads: exact to a fraction of a degree after the hand-over,
    # and it holds the lowest swept speed under the file's load on the nominal plant
    assert flux["angle_error_rms_deg"] < 0.5 and flux["angle_error_max_deg"] < 3.0
    assert not flux["lock_lost"] and flux["lowest_held_rpm"] == pytest.approx(6.0)
    assert pll["angle_error_rms_deg"] < 2.0 and not pll["lock_lost"]


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
