"""``pmsmjax compare --machine six-phase|five-phase``: the multi-phase control schemes side by side through
the same comparison engine as the three-phase controls.

Independent checks: the book-9.5 equivalence (VSD and double dq designed equivalently give the same
response, derived in controllers/multiphase.py and tested there on traces); the steady torque balance
``T_e = T_L + B w`` of the mechanics; one-line refusals before anything is written.
"""

import json

import pytest

from pmsmjax.cli import main
from pmsmjax.presets.five_phase import five_phase_motor
from pmsmjax.units import rpm_to_rad_s

# 500 r/min, 4 pole pairs: 30 ms electrical period, so the default 2-period ripple window is whole periods
RUN = ["--speed-rpm", "500", "--load-nm", "5", "--load-time-s", "0.1", "--duration-s", "0.36"]


@pytest.mark.slow
def test_six_phase_vsd_and_double_dq_compare_equal(tmp_path):
    out = tmp_path / "six"
    args = ["compare", "--machine", "six-phase", "--control", "vsd,double-dq", "--bridge", "averaged"]
    assert main([*args, "--out", str(out), "--no-figures", *RUN]) == 0
    report = json.loads((out / "compare.json").read_text())
    assert report["settings"]["machine"] == "six-phase"
    vsd, ddq = report["controllers"]["vsd"], report["controllers"]["double-dq"]
    for key in ("itae", "dip_rpm", "peak_current_a", "mean_torque_nm"):
        assert ddq[key] == pytest.approx(vsd[key], rel=1e-6), key


def test_five_phase_compare_holds_the_torque_balance(tmp_path):
    out = tmp_path / "five"
    args = ["compare", "--machine", "five-phase", "--control", "vsd", "--out", str(out), *RUN]
    assert main(args) == 0
    entry = json.loads((out / "compare.json").read_text())["controllers"]["vsd"]
    motor = five_phase_motor()
    # steady state in the analysis window: electromagnetic torque = load + viscous friction
    expected = 5.0 + float(motor.B) * rpm_to_rad_s(500.0)
    assert entry["mean_torque_nm"] == pytest.approx(expected, rel=2e-3)
    assert entry["switching_frequency_hz"] == pytest.approx(10e3, rel=1e-6)
    for name in ("compare_speed.png", "compare_ripple.png", "compare_flux.png"):
        assert (out / name).stat().st_size > 0


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--control", "dtc"], "--control 'dtc': unknown dtc; choose from vsd, double-dq, conventional, pr"),
        (["--estimator", "smo"], "--estimator applies to the three-phase drive"),
        (["--equal-switching"], "--equal-switching applies to the three-phase drive"),
    ],
)
def test_bad_multiphase_flags_are_refused_before_writing(extra, message, tmp_path, capsys):
    out = tmp_path / "never"
    assert main(["compare", "--machine", "six-phase", *extra, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


@pytest.mark.parametrize(
    "machine, extra, message",
    [
        ("six-phase", ["--speed-rpm", "5000"], "--speed-rpm 5000: at 10 N m the drive needs 209 V"),
        # the same torque constant as the book motor: 15 A hold 0.95 x 16.4 N m at standstill
        ("five-phase", ["--load-nm", "30"], "give a load of at most 15.6 N m"),
    ],
)
def test_unreachable_multiphase_points_are_refused_before_running(machine, extra, message, tmp_path, capsys):
    out = tmp_path / "never"
    assert main(["compare", "--machine", machine, *extra, "--out", str(out)]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()
