"""Issue 14 studies of the chapter 5 observers: the observer figures (hand-computed cases), the Monte Carlo
kernel's in-scan figures against the NumPy definitions on a full trace, ``compare --estimator`` and a
sensorless Monte Carlo study. Short runs keep it quick."""

import json
import math
from types import SimpleNamespace

import equinox as eqx
import numpy as np
import pytest

import pmsmjax
from pmsmjax.analysis import observer_errors as om
from pmsmjax.checks.validation import ParameterError
from pmsmjax.cli import main
from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.studies.control_comparison import (
    ControllerCompareSettings,
    LowSpeedSweep,
    compare_estimators,
    estimator_table,
)
from pmsmjax.units import rpm_to_rad_s
from tuning.montecarlo import run_study
from tuning.montecarlo import study as mc_study
from tuning.montecarlo.kernel import run_metrics
from tuning.montecarlo.study import SENSORLESS_TOLERANCES, Study

TS = 1e-4


def fake_trace(angle_error_rad, speed_error, speed_ref=100.0):
    """A trace whose estimate is off the plant by the given per-period errors (NumPy, period TS)."""
    n = len(angle_error_rad)
    theta = np.linspace(0.0, 40.0, n)
    omega = np.full(n, speed_ref)
    return SimpleNamespace(
        t=np.arange(n) * TS,
        theta_e=theta,
        theta_e_est=theta + np.asarray(angle_error_rad),
        omega_m=omega,
        omega_m_est=omega + np.asarray(speed_error),
        speed_ref=np.full(n, speed_ref),
    )


def test_observer_errors_of_a_hand_made_trace():
    n = 1500  # 0.15 s; periods from 0.05 s (k = 500) count
    e = np.zeros(n)
    e[:500] = 3.0  # before convergence: ignored, although out of lock
    e[600:700] = 0.2  # 100 periods of 0.2 rad
    e[800:901] = -2.0  # 101 periods out of lock: 10.1 ms > 10 ms
    trace = fake_trace(e, np.zeros(n))
    out = om.observer_errors(trace, TS)
    rms = math.sqrt((100 * 0.2**2 + 101 * 2.0**2) / 1000)
    assert out["angle_error_rms_deg"] == pytest.approx(math.degrees(rms), rel=1e-9)
    assert out["angle_error_max_deg"] == pytest.approx(math.degrees(2.0), rel=1e-9)
    assert out["lock_lost"] and out["longest_out_of_lock_s"] == pytest.approx(101 * TS)
    e[900] = 0.0  # now exactly 100 periods (10 ms): not longer than the window
    assert not om.observer_errors(fake_trace(e, np.zeros(n)), TS)["lock_lost"]
    # the speed criterion alone: 0.5 * 100 + 1 = 51 rad/s
    w = np.zeros(n)
    w[1000:1200] = 52.0
    out = om.observer_errors(fake_trace(np.zeros(n), w), TS)
    assert out["lock_lost"] and out["speed_error_rms_rpm"] == pytest.approx(
        30 / math.pi * math.sqrt(200 * 52.0**2 / 1000), rel=1e-9
    )
    w[1000:1200] = 50.0
    assert not om.observer_errors(fake_trace(np.zeros(n), w), TS)["lock_lost"]


def test_angle_error_wraps():
    e = om.angle_error(np.array([3.1, -3.1, 0.1]), np.array([-3.1, 3.1, 2 * math.pi]))
    np.testing.assert_allclose(e, [6.2 - 2 * math.pi, 2 * math.pi - 6.2, 0.1], atol=1e-12)


def test_speed_held_definition():
    n = 1000
    trace = fake_trace(np.zeros(n), np.zeros(n), speed_ref=10.0)
    trace.omega_m = trace.omega_m.copy()
    trace.omega_m[-1] = 10.0 - 0.99  # error 0.99 <= 10 % of 10 rad/s
    assert om.speed_held(trace, TS, 0.08)["held"]
    trace.omega_m[-1] = 10.0 - 1.01
    assert not om.speed_held(trace, TS, 0.08)["held"]
    trace.omega_m[-1] = 10.0
    trace.theta_e_est = trace.theta_e.copy()
    trace.theta_e_est[-1] += math.radians(31.0)
    assert not om.speed_held(trace, TS, 0.08)["held"]


# ---------------------------------------------------------------- the kernel against the full trace


@pytest.mark.parametrize(
    "observer, r_factor, speed_rpm, lost",
    [("smo", 1.3, 600.0, False), ("mras", 1.3, 60.0, True)],  # the second loses lock (measured)
)
def test_kernel_observer_figures_equal_those_of_the_full_trace(observer, r_factor, speed_rpm, lost):
    drive = pmsmjax.presets.sensorless_drive(observer, startup=True)
    drive = eqx.tree_at(lambda d: d.machine.motor.R, drive, drive.machine.motor.R * r_factor)
    scenario = Scenario(
        duration_s=0.3,
        speed_ref=Profile.ramp(0.06, 0.12, rpm_to_rad_s(400.0), rpm_to_rad_s(speed_rpm)),
        load_torque=Profile.step(0.05, 0.0, 8.0),
    )
    m, _ = run_metrics(drive, scenario, 0.05, decimate=40)
    ref = om.observer_errors(pmsmjax.simulate(drive, scenario), drive.Ts)
    for key in ("angle_error_rms_deg", "angle_error_max_deg", "speed_error_rms_rpm"):
        assert float(m[key]) == pytest.approx(ref[key], rel=1e-9, abs=1e-12), key
    assert bool(m["lock_lost"]) == ref["lock_lost"] == lost


# ------------------------------------------------------------------------------ compare --estimator

SHORT = ControllerCompareSettings(bridge="averaged")  # the book scenario, averaged bridge
SWEEP = LowSpeedSweep(speeds_rpm=(300.0, 30.0), hot_r_factor=None, duration_s=0.5, judge_from_s=0.4)


@pytest.fixture(scope="module")
def compared():
    return compare_estimators(["smo", "ekf"], None, SHORT, SWEEP)


def test_compare_estimators_figures(compared):
    for name in ("smo", "ekf"):
        e = compared["controllers"][name]
        ref = om.observer_errors(compared["traces"][name], 1e-4)
        assert e["angle_error_rms_deg"] == ref["angle_error_rms_deg"]
        # the bar for a model-exact observer at speed, and the book scenario ridden through
        assert e["angle_error_rms_deg"] < 2.0 and not e["lock_lost"]
        assert abs(e["final_speed_rpm"] - 1000.0) < 5.0
        runs = e["low_speed_runs"]
        assert [r["speed_rpm"] for r in runs] == [300.0, 30.0]
        held = [r["held"] for r in runs]
        expected = None if not held[0] else (30.0 if held[1] else 300.0)
        assert e["lowest_held_rpm"] == expected
    table = estimator_table(compared).splitlines()
    assert len(table) == 4 and table[2].startswith("| smo |")


def test_compare_estimator_flags_are_checked(tmp_path, capsys):
    for argv, words in (
        (["--estimator", "smo,nope"], "unknown nope; choose from smo, smo-pll"),
        (["--estimator", "smo", "--control", "dtc"], "book PI drive"),
        (["--estimator", "smo", "--equal-switching"], "--equal-switching does not apply"),
    ):
        assert main(["compare", *argv, "--out", str(tmp_path / "x")]) != 0
        assert words in capsys.readouterr().err
        assert not (tmp_path / "x").exists()


# ------------------------------------------------------------------------- sensorless Monte Carlo


def test_sensorless_study_perturbs_the_plant_not_the_observer():
    study = Study(n=4, estimator="smo", duration_s=0.1, load_time_s=0.06, decimate=20)
    assert {k: v["tolerance"] for k, v in study.parameters.items()} == SENSORLESS_TOLERANCES
    drive = mc_study.build_drive(study)
    names = tuple(study.parameters)
    values = np.array([2.0, 7e-3, 8e-3, 0.2])
    varied, _ = mc_study.apply_sample(drive, study, names, values)
    m = varied.machine.motor
    np.testing.assert_allclose([m.R, m.L_d, m.L_q, m.psi_f], values)
    observer_model = varied.estimator.observer.model
    nominal = drive.machine.motor
    assert float(observer_model.R) == float(nominal.R) != 2.0
    assert float(observer_model.psi_f) == float(nominal.psi_f)
    assert float(varied.controller.model.R) == float(nominal.R)
    with pytest.raises(ParameterError, match="unknown observer"):
        Study(estimator="smoo")


def test_sensorless_study_summary(tmp_path):
    study = Study(
        n=4, seed=1, estimator="smo", duration_s=0.1, load_time_s=0.06, decimate=20, sensitivity_runs=0
    )
    s = run_study(study, tmp_path, progress=False, figures=False)
    assert s["failures"]["lock_lost"]["count"] == 0
    for key in ("angle_error_rms_deg", "angle_error_max_deg", "speed_error_rms_rpm"):
        assert s["metrics"][key]["n"] == 4
    assert 0.0 < s["metrics"]["angle_error_rms_deg"]["p95"] < s["metrics"]["angle_error_max_deg"]["max"]
    data = json.loads((tmp_path / "summary.json").read_text())
    assert data["study"]["estimator"] == "smo"


def test_montecarlo_command_with_an_estimator(tmp_path, capsys):
    config = tmp_path / "study.toml"
    config.write_text(
        '[study]\nn = 2\ndecimate = 20\n[drive]\nestimator = "mras"\n'
        "[scenario]\nduration_s = 0.1\nload_time_s = 0.06\n"
    )
    out = tmp_path / "mc"
    argv = ["montecarlo", "--config", str(config), "--sensitivity-runs", "2", "--no-figures", "--no-progress"]
    assert main([*argv, "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "angle_error_rms_deg" in printed and "loss of lock: 0 runs" in printed
    s = json.loads((out / "summary.json").read_text())
    assert s["study"]["estimator"] == "mras"
    assert set(s["parameters"]) == set(SENSORLESS_TOLERANCES)
    # forward-mode sensitivities through the sensorless closed loop (I/f start included) are finite
    per_unit = s["sensitivities"]["per_unit"]
    assert all(math.isfinite(v) for m in per_unit.values() for v in m.values())
    # an unknown observer is refused before any work
    with pytest.raises(SystemExit):
        main(["montecarlo", "--estimator", "nope", "--out", str(tmp_path / "x")])
    assert "invalid choice: 'nope'" in capsys.readouterr().err and not (tmp_path / "x").exists()
