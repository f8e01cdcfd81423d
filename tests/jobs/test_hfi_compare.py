"""``compare --estimator`` with the chapter 6 estimators (hfi-rotating, hfi-pulsating,
hybrid) on their own scenarios. The angle figures are recomputed here from the traces with an
independent modulo-pi formula (``np.mod``), the accuracy bar (5 el. deg RMS modulo pi, no
loss of lock) is checked on the 60 r/min reversal under load, and nonsense mixes are refused before any
work. Short runs (0.8 s, averaged bridge) keep it quick."""

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from pmsmjax.analysis import observer_errors as om
from pmsmjax.cli import main
from pmsmjax.cli.compare import CHAPTER6_NAMES
from pmsmjax.estimators import HYBRID_OBSERVERS, INJECTION_OBSERVERS
from pmsmjax.jobs.control_comparison import ControllerCompareSettings
from pmsmjax.jobs.estimator_comparison import compare_estimators, estimator_table
from pmsmjax.units import rpm_to_rad_s

TS = 1e-4
AVERAGED = ControllerCompareSettings(bridge="averaged")  # load_nm 10


def rms_modulo_pi_deg(theta_est, theta, t, after=om.CONVERGED_AFTER_S):
    """RMS of the angle error folded into [-90, 90) el. degrees with np.mod (not the code's wrap)."""
    d = np.degrees(np.asarray(theta_est, np.float64) - np.asarray(theta, np.float64))
    folded = np.mod(d + 90.0, 180.0) - 90.0
    keep = np.asarray(t) >= after - 0.5 * TS
    return float(np.sqrt(np.mean(folded[keep] ** 2)))


def test_chapter6_names_agree_with_the_registry():
    assert set(CHAPTER6_NAMES) == set(INJECTION_OBSERVERS) | set(HYBRID_OBSERVERS)


def test_modulo_pi_error_and_angle_only_lock_by_hand():
    n = 1500  # periods from 0.05 s (k = 500) count
    theta = np.linspace(0.0, 30.0, n)
    e = np.zeros(n)
    e[600:700] = math.pi + 0.2  # the other pole, 0.2 rad off: 0.2 modulo pi
    e[800:901] = math.radians(50.0)  # 101 periods beyond 45 deg: out of lock modulo pi
    trace = SimpleNamespace(
        t=np.arange(n) * TS,
        theta_e=theta,
        theta_e_est=theta + e,
        omega_m=np.zeros(n),
        omega_m_est=np.full(n, 5.0),  # 5 rad/s off a zero reference: out of lock by speed
        speed_ref=np.zeros(n),
    )
    out = om.observer_errors(trace, TS, modulo_pi=True, speed_lock=False)
    rms = math.sqrt((100 * 0.2**2 + 101 * math.radians(50.0) ** 2) / 1000)
    assert out["angle_error_rms_deg"] == pytest.approx(math.degrees(rms), rel=1e-9)
    assert out["angle_error_max_deg"] == pytest.approx(50.0, rel=1e-9)
    assert out["lock_lost"] and out["longest_out_of_lock_s"] == pytest.approx(101 * TS)
    assert out["angle_modulo"] == "pi"
    e[900] = math.radians(40.0)  # 100 periods beyond 45 deg (10 ms): not longer than the window
    trace.theta_e_est = theta + e
    assert not om.observer_errors(trace, TS, modulo_pi=True, speed_lock=False)["lock_lost"]
    # the same trace modulo 2 pi: the other pole is out of lock by angle (pi + 0.2 > pi/2) for 100
    # periods only, but the speed criterion (5 > 1 rad/s) holds from the start
    full = om.observer_errors(trace, TS)
    assert full["angle_modulo"] == "2pi" and full["angle_error_max_deg"] == pytest.approx(
        math.degrees(math.pi - 0.2), rel=1e-9
    )
    assert full["lock_lost"] and full["longest_out_of_lock_s"] == pytest.approx(1000 * TS)


@pytest.fixture(scope="module")
def injection_reversal():
    return compare_estimators(
        ["hfi-rotating", "hfi-pulsating"], None, AVERAGED, None, scenario="slow-reversal"
    )


def test_injection_methods_through_the_slow_reversal(injection_reversal):
    for name in ("hfi-rotating", "hfi-pulsating"):
        e = injection_reversal["controllers"][name]
        tr = injection_reversal["traces"][name]
        assert math.degrees(float(tr.theta_e[0])) == pytest.approx(30.0)  # started 30 deg off
        assert e["angle_modulo"] == "pi"
        assert e["angle_error_rms_deg"] == pytest.approx(rms_modulo_pi_deg(tr.theta_e_est, tr.theta_e, tr.t))
        # the accuracy bar: below 5 el. deg RMS modulo pi, no loss of lock, the reversal done
        assert e["angle_error_rms_deg"] < 5.0 and not e["lock_lost"]
        assert abs(e["final_speed_rpm"] + 60.0) < 3.0
        w = np.asarray(tr.omega_m)
        assert w.max() > rpm_to_rad_s(50.0) and w[-1] < 0.0
    table = estimator_table(injection_reversal).splitlines()
    assert len(table) == 4 and "| pi |" in table[2]
    assert injection_reversal["settings"]["scenario"] == "slow-reversal"


def test_hybrid_at_standstill_under_load_from_the_wrong_pole():
    # 150 deg off: the injection alone would lock to the d axis at 180 deg (the wrong pole); the
    # hybrid's polarity pulses flip it, so the error is scored modulo 2 pi
    out = compare_estimators(["hybrid"], None, AVERAGED, None, scenario="standstill", initial_angle_deg=150.0)
    e, tr = out["controllers"]["hybrid"], out["traces"]["hybrid"]
    assert e["angle_modulo"] == "2pi" and not e["lock_lost"]
    err = np.degrees(om.angle_error(tr.theta_e_est, tr.theta_e))[np.asarray(tr.t) >= 0.06]
    assert np.abs(err).max() < 30.0 and e["angle_error_rms_deg"] < 5.0
    assert abs(e["final_speed_rpm"]) < 5.0


def test_cli_writes_the_injection_table(tmp_path):
    out = tmp_path / "c"
    assert main(["compare", "--estimator", "hfi-pulsating", "--no-figures", "--out", str(out)]) == 0
    report = json.loads((out / "compare.json").read_text())
    assert report["settings"]["scenario"] == "standstill"  # the injection methods' default
    assert report["settings"]["initial_angle_deg"] == 30.0
    e = report["estimators"]["hfi-pulsating"]
    assert e["angle_modulo"] == "pi" and not e["lock_lost"] and e["angle_error_rms_deg"] < 5.0
    assert "| hfi-pulsating |" in (out / "compare_estimators.md").read_text()


@pytest.mark.parametrize(
    "argv, words",
    [
        (["--estimator", "smo,hfi-rotating"], "mixes chapter 5 observers (smo)"),
        (["--estimator", "hfi-rotating", "--scenario", "book"], "--scenario standstill or slow-reversal"),
        (["--estimator", "hfi-rotating,hybrid", "--scenario", "reversal"], "does not suit hfi-rotating"),
        (["--estimator", "hfi-rotating", "--motor", "book"], "give --motor book_salient"),
        (["--estimator", "hfi-rotating", "--speed-rpm", "500"], "--speed-rpm sets the book scenario"),
        (["--estimator", "smo", "--scenario", "standstill"], "--scenario standstill is for the chapter 6"),
        (["--estimator", "ekf", "--initial-angle-deg", "40"], "--initial-angle-deg is for the chapter 6"),
        (["--control", "pi", "--scenario", "standstill"], "--scenario belongs to --estimator"),
    ],
)
def test_nonsense_mixes_are_refused(tmp_path, capsys, argv, words):
    assert main(["compare", *argv, "--out", str(tmp_path / "x")]) != 0
    err = capsys.readouterr().err
    assert words in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x").exists()
