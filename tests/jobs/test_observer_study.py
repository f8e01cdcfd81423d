"""Studies of the chapter 5 observers: the Monte Carlo kernel's in-scan figures against the NumPy
definitions on a full trace, ``compare --estimator`` and a sensorless Monte Carlo study (the figures
themselves on hand-computed cases: tests/analysis/test_observer_errors.py). Short runs keep it quick."""

import json
import math

import equinox as eqx
import numpy as np
import pytest

import pmsmjax
from pmsmjax.analysis import observer_errors as om
from pmsmjax.cli import main
from pmsmjax.jobs.control_comparison import ControllerCompareSettings
from pmsmjax.jobs.estimator_comparison import LowSpeedSweep, compare_estimators, estimator_table
from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.spec.validation import ParameterError
from pmsmjax.units import rpm_to_rad_s
from tuning.montecarlo import run_study
from tuning.montecarlo import study as mc_study
from tuning.montecarlo.kernel import run_metrics
from tuning.montecarlo.study import SENSORLESS_TOLERANCES, Study

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


@pytest.mark.slow
def test_compare_estimators_figures(compared):
    for name in ("smo", "ekf"):
        e = compared["controllers"][name]
        ref = om.observer_errors(compared["traces"][name], 1e-4)
        assert e["angle_error_rms_deg"] == ref["angle_error_rms_deg"]
        # the accuracy bar for a model-exact observer at speed, and the book scenario ridden through
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


@pytest.mark.slow
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
