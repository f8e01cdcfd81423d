"""Datasheet keys of ``[motor]`` (pmsmjax/spec/datasheet.py) against hand computations.

Conventions as Kollmorgen's motor data legend states them (kollmorgen.com, "Motor Data Legend": ``KTrms``
torque per A RMS; ``KE`` the induced EMF between two terminals, RMS, per 1000 r/min; ``R20`` and ``L``
measured phase to phase). The numbers are illustrative values of a 400 W, 8-pole servo of that kind, not a
catalogue row; the hobby motor's ``kv = 270`` r/min/V with 7 pole pairs is that of the common 5065-size
outrunners (illustrative too).
"""

import math

import pytest

from pmsmjax.io.drive_files import drive_spec
from pmsmjax.spec.validation import ParameterError

REST = """pole_pairs = {p}
J = 3.4e-5
B = 1e-5
[ratings]
rated_speed_rpm = 3000.0
rated_current_a = 3.0
max_current_a = 9.0
[inverter]
u_dc_v = 320.0
switching_frequency_hz = 10000.0
"""


def spec_of(tmp_path, motor: str, p: int = 4):
    path = tmp_path / "drive.toml"
    path.write_text("[motor]\n" + motor + "\n" + REST.format(p=p))
    return drive_spec(str(path))


def test_rms_catalogue_constants_by_hand(tmp_path):
    spec = spec_of(
        tmp_path, "r_ll_ohm = 1.9\nl_ll_h = 0.0071\nke_v_rms_per_krpm_ll = 40.0\nkt_nm_per_a_rms = 0.66"
    )
    # R = 1.9 / 2; L_d = L_q = 7.1 mH / 2
    assert spec.motor["R"] == pytest.approx(0.95, rel=1e-12)
    assert spec.motor["L_d"] == spec.motor["L_q"] == pytest.approx(3.55e-3, rel=1e-12)
    # 40 V RMS line to line at 1000 r/min: 56.569 V peak, / sqrt(3) = 32.660 V phase peak, at
    # omega_e = 4 * 104.72 rad/s = 418.88 rad/s: psi_f = 32.660 / 418.88 = 0.077970 Wb
    assert spec.motor["psi_f"] == pytest.approx(0.077970, rel=2e-5)
    # kt = 0.66 N m / A RMS = 0.46669 N m / A peak = 1.5 * 4 * psi_f: psi_f = 0.077782 (0.24 % below)
    note = spec.derived["motor.psi_f"]
    assert "ke_v_rms_per_krpm_ll = 40 V/krpm" in note and "RMS line-to-line" in note
    assert "kt_nm_per_a_rms agrees within 0.2 %" in note
    assert "line-to-line resistance" in spec.derived["motor.R"]


def test_peak_and_rms_keys_give_one_flux(tmp_path):
    rms = spec_of(tmp_path, "R = 0.95\nL_d = 3.5e-3\nL_q = 3.5e-3\nke_v_rms_per_krpm_ll = 40.0")
    peak = spec_of(
        tmp_path, f"R = 0.95\nL_d = 3.5e-3\nL_q = 3.5e-3\nke_v_peak_per_krpm_ll = {40 * math.sqrt(2)}"
    )
    per_peak_amp = spec_of(
        tmp_path, f"R = 0.95\nL_d = 3.5e-3\nL_q = 3.5e-3\nkt_nm_per_a_peak = {1.5 * 4 * 0.07797}"
    )
    assert peak.motor["psi_f"] == pytest.approx(rms.motor["psi_f"], rel=1e-12)
    assert per_peak_amp.motor["psi_f"] == pytest.approx(0.07797, rel=1e-12)


def test_kv_of_a_hobby_motor_by_hand(tmp_path):
    spec = spec_of(tmp_path, "R = 0.04\nL_d = 2.5e-5\nL_q = 2.5e-5\nkv_rpm_per_v = 270.0", p=7)
    # 1 V peak line to line per 270 r/min: 1/sqrt(3) V phase peak at omega_e = 7 * 270 * 2 pi / 60 rad/s
    psi_f = (1.0 / math.sqrt(3.0)) / (7 * 270 * 2 * math.pi / 60)
    assert psi_f == pytest.approx(0.0029171, rel=1e-4)
    assert spec.motor["psi_f"] == pytest.approx(psi_f, rel=1e-12)
    # the torque constant per A peak ODrive's users take, 8.27 / kv N m/A
    assert 1.5 * 7 * spec.motor["psi_f"] == pytest.approx(8.27 / 270, rel=1e-3)


@pytest.mark.parametrize(
    "motor, match",
    [
        ("R = 0.95\nr_ll_ohm = 1.9\nL_d = 3e-3\nL_q = 3e-3\npsi_f = 0.08", "both r_ll_ohm and R"),
        ("R = 0.95\nl_ll_h = 7e-3\nL_q = 3e-3\npsi_f = 0.08", "both l_ll_h and L_q"),
        (
            "R = 0.95\nL_d = 3e-3\nL_q = 3e-3\npsi_f = 0.08\nkv_rpm_per_v = 100.0",
            "both kv_rpm_per_v and psi_f",
        ),
        ("R = 0.95\nL_d = 3e-3\nL_q = 3e-3\nke_v_per_krpm_ll = 40.0", "peak or RMS"),
        ("R = 0.95\nL_d = 3e-3\nL_q = 3e-3\nkt_nm_per_a = 0.66", "kt_nm_per_a_rms or kt_nm_per_a_peak"),
        (
            "R = 0.95\nL_d = 3e-3\nL_q = 3e-3\nke_v_rms_per_krpm_ll = 40.0\nke_v_peak_per_krpm_ll = 56.6",
            "both ke_v_peak_per_krpm_ll and ke_v_rms_per_krpm_ll",
        ),
        (  # the RMS torque constant typed as per A peak: a factor sqrt(2)
            "R = 0.95\nL_d = 3e-3\nL_q = 3e-3\nke_v_rms_per_krpm_ll = 40.0\nkt_nm_per_a_peak = 0.66",
            "disagree.*sqrt\\(2\\): one is peak, the other RMS",
        ),
        (
            "R = 0.95\nL_d = 3e-3\nL_q = 3e-3\nkt_nm_per_a_rms = -0.66",
            "kt_nm_per_a_rms must be a number above 0",
        ),
    ],
)
def test_careless_datasheet_keys_are_refused_in_one_line(tmp_path, motor, match):
    with pytest.raises(ParameterError, match=match) as info:
        spec_of(tmp_path, motor)
    assert "\n" not in str(info.value) and "[motor]" in str(info.value)
