"""Magnet flux harmonics and cogging identified from a log the code under test did not make
(tuning/identify/flux_harmonics_fit.py, cogging_fit.py, ripple_stage.py).

The log is ``tuning.identify.heat_run_log`` with ``ripple=RIPPLE``: SciPy's DOP853 integrates the warm dq
machine with the 5th and 7th flux harmonics (their back-EMF from the phase fluxes, Clarke-transformed) under
a NumPy current loop that reads faulty sensors (offsets, a gain mismatch, a turned encoder) behind an
inverter with dead time, while a dynamometer holds +-40 rad/s and a torque sensor (10 mN m noise) logs the
shaft torque with cogging of orders 6 and 12, friction and the harmonics' torque. The same log carries
the heat run's temperature (25 to 90 degC).

Bounds: amplitudes within 5 %, phases within 3 deg; the fits are also checked against their own 95 %
intervals, and the fit without the harmonics against the same log is shown to be wrong.
"""

import math
import re

import numpy as np
import pytest

from pmsmjax.spec.validation import ParameterError
from tuning.identify.cogging_fit import fit_cogging
from tuning.identify.heat_run_log import DEAD_TIME_V, MOTOR, RIPPLE, SENSORS, heat_run_log
from tuning.identify.sensor_errors import corrected_columns, identify_sensor_errors, sensor_log_from_columns

G_A = SENSORS["current_gain"][0]
SLOW = (40.0, -40.0)  # rad/s, both directions


def _fit(cols, flux_orders=(5, 7), cogging_orders=(6, 12)):
    slog, c = sensor_log_from_columns(cols)
    errors = identify_sensor_errors(slog, reference_c=20.0, dead_time=True, flux_orders=flux_orders)
    corrected = corrected_columns(c, errors)
    corrected["temperature_c"] = c["temperature_c"]
    cog = fit_cogging(corrected, errors.machine, MOTOR["pole_pairs"], cogging_orders, slog.segments)
    return errors, cog


@pytest.fixture(scope="module")
def ripple_log():
    return heat_run_log(ripple=RIPPLE, speeds_rad_s=SLOW)


@pytest.fixture(scope="module")
def fitted(ripple_log):
    return _fit(ripple_log)


def _check_rows(rows, truth, rel=0.05, deg=3.0):
    for row, (order, amplitude, phase) in zip(rows, truth, strict=True):
        a, p = row["amplitude"], row["phase_rad"]
        assert row["order"] == order and a["identifiable"], row
        assert abs(a["value"] / amplitude - 1.0) < rel, row
        assert abs(math.degrees(math.remainder(p["value"] - phase, 2 * math.pi))) < deg, row
        assert abs(a["value"] - amplitude) < 3.0 * a["stderr"] + 1e-3 * amplitude, row  # inside its interval


def test_flux_harmonics_with_the_sensor_errors(fitted):
    """Measured: 5th 1.6002 mWb (+0.01 %), 0.70 deg off by 0.01; 7th 0.7994 mWb (-0.07 %), 0.2 deg."""
    errors = fitted[0]
    _check_rows(errors.summary["flux_harmonics"]["rows"], RIPPLE["flux"])
    s = errors.summary
    assert abs(errors.machine["R"] / (MOTOR["R"] / G_A) - 1.0) < 0.01
    assert abs(errors.machine["psi_f"] / MOTOR["psi_f"] - 1.0) < 0.005
    assert abs(errors.machine["V_dt"] / DEAD_TIME_V - 1.0) < 0.01
    for e, truth in zip(s["current_offset_a"], SENSORS["current_offset_a"], strict=True):
        assert abs(e["value"] - truth) < 0.005
    assert abs(s["encoder_offset_rad"]["value"] - SENSORS["encoder_offset_rad"]) < math.radians(0.3)


def test_cogging_from_the_shaft_torque(fitted):
    """Measured: 6th 0.1501 N m (+0.06 %), 12th 0.0501 N m (+0.15 %), phases within 0.05 deg; the torque
    scale is 1 / g_a (the torque sensor sees sensor a's absolute gain)."""
    cog = fitted[1]
    _check_rows(cog["rows"], RIPPLE["cogging"])
    assert cog["torque_scale"]["value"] == pytest.approx(1.0 / G_A, rel=2e-4)
    friction = cog["friction"]["offset_forward_nm"]["value"]
    assert friction == pytest.approx(-(RIPPLE["B"] * SLOW[0] + RIPPLE["coulomb_nm"]), abs=1e-3)
    assert cog["residual_rms_nm"] < 1.3 * RIPPLE["torque_noise_nm"]


def test_without_the_harmonics_the_fit_is_wrong(ripple_log, fitted):
    """Left out, the harmonics' back-EMF (at orders 5 and 7 in the stator frame, where the dead time's
    six-step pattern also lies) pushes into V_dt, R and the encoder offset; the torque of the harmonics,
    left out of the torque balance, lands on the 6th cogging order. Measured: R +2.2 %, V_dt -5.1 %,
    encoder -0.05 deg, residual x47; cogging 6th +49 % and 22 deg off."""
    errors, cog = _fit(ripple_log, flux_orders=())
    assert errors.machine["R"] / (MOTOR["R"] / G_A) - 1.0 > 0.015
    assert errors.machine["V_dt"] / DEAD_TIME_V - 1.0 < -0.03
    assert errors.summary["residual_rms_vs"] > 20 * fitted[0].summary["residual_rms_vs"]
    six = cog["rows"][0]
    assert six["amplitude"]["value"] / RIPPLE["cogging"][0][1] - 1.0 > 0.3
    assert abs(math.degrees(six["phase_rad"]["value"] - RIPPLE["cogging"][0][2])) > 10.0


def test_a_cogging_fit_needs_the_shaft_torque(ripple_log):
    cols = {k: v for k, v in ripple_log.items() if k != "T_L"}
    with pytest.raises(ParameterError, match=r"--cogging-orders needs the shaft torque T_L"):
        _fit(cols)


def test_a_speed_that_is_not_held_is_refused(ripple_log):
    cols = dict(ripple_log)
    cols["omega_m"] = cols["omega_m"] * (1.0 + 0.2 * np.sin(np.arange(cols["omega_m"].size) / 50.0))
    with pytest.raises(ParameterError, match=r"held speed.*hold the speed"):
        _fit(cols)


def test_the_heat_run_identification_with_ripple_in_the_log():
    """The heat run of tests/tuning/test_identify_temperature.py (60 and 120 rad/s, 60 K of warming) with
    the flux harmonics and cogging in the motor: with --flux-harmonics 5,7 the same bounds hold (offsets
    within 5 mA, gain ratio 0.2 %, encoder 0.3 deg, R 1 %, L 2 %, psi_f 0.5 %, coefficients 5 %, thermal
    network 10 %), and the harmonics and cogging come out as on the slow run."""
    from tuning.identify.heat_run_log import THERMAL
    from tuning.identify.thermal_network_fit import temperature_report

    cols = heat_run_log(ripple=RIPPLE)
    slog, c = sensor_log_from_columns(cols)
    errors, cog = _fit(cols)
    corrected = corrected_columns(c, errors)
    corrected["temperature_c"] = c["temperature_c"]
    report = temperature_report(errors, corrected, slog.segments, None)
    assert abs(report["R"]["value"] / (MOTOR["R"] / G_A) - 1.0) < 0.01
    assert abs(report["psi_f"]["value"] / MOTOR["psi_f"] - 1.0) < 0.005
    for name in ("r_temp_coeff_per_k", "psi_f_temp_coeff_per_k"):
        assert report[name]["identifiable"] and abs(report[name]["value"] / MOTOR[name] - 1.0) < 0.05
    for name in ("L_d", "L_q"):
        assert abs(errors.machine[name] / (MOTOR[name] / G_A) - 1.0) < 0.02, name
    s = errors.summary
    for e, truth in zip(s["current_offset_a"], SENSORS["current_offset_a"], strict=True):
        assert abs(e["value"] - truth) < 0.005, e
    ratio = SENSORS["current_gain"][1] / SENSORS["current_gain"][0]
    assert abs(s["current_gain"][1]["value"] / ratio - 1.0) < 0.002
    assert abs(s["encoder_offset_rad"]["value"] - SENSORS["encoder_offset_rad"]) < math.radians(0.3)
    network = report["thermal_network"]
    for name in ("r_th_k_per_w", "c_th_j_per_k"):
        assert abs(network[name]["value"] / THERMAL[name] - 1.0) < 0.1, name
    _check_rows(s["flux_harmonics"]["rows"], RIPPLE["flux"])
    _check_rows(cog["rows"], RIPPLE["cogging"])


PRIOR = (
    "[motor]\nR = 0.5\nL_d = 0.002\nL_q = 0.003\npsi_f = 0.08\npole_pairs = 4\nJ = 0.001\nB = 0.0001\n"
    '[sensor]\nkind = "encoder"\nlines = 2500\n'
)


@pytest.mark.slow
def test_identify_writes_the_harmonics_to_motor_toml(ripple_log, tmp_path, capsys):
    """``identify --dead-time --flux-harmonics 5,7 --cogging-orders 6,12`` on the slow run's CSV: the
    harmonics printed with their intervals, motor.toml's [harmonics] read back by the drive-file reader."""
    from pmsmjax.cli import main
    from pmsmjax.io.drive_files import drive_spec
    from pmsmjax.io.logs import write_csv_atomic

    write_csv_atomic(tmp_path / "log.csv", ripple_log)
    (tmp_path / "prior.toml").write_text(PRIOR)
    out = tmp_path / "id"
    argv = ["identify", str(tmp_path / "log.csv"), "--dead-time", "--flux-harmonics", "5,7",
            "--cogging-orders", "6,12", "--motor", str(tmp_path / "prior.toml"), "--out", str(out),
            "--fix", "J=0.001", "--load", "none", "--no-figures"]  # fmt: skip
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "flux order 5" in text and "cogging order 12" in text
    spec = drive_spec(str(out / "motor.toml"))
    flux, cogging = spec.harmonics["flux"], spec.harmonics["cogging"]
    for rows, truth in ((flux, RIPPLE["flux"]), (cogging, RIPPLE["cogging"])):
        for (order, a, phi), (k, a0, phi0) in zip(rows, truth, strict=True):
            assert order == k and abs(a / a0 - 1.0) < 0.05
            assert abs(math.degrees(math.remainder(phi - phi0, 2 * math.pi))) < 3.0
    assert abs(spec.motor["psi_f"] / MOTOR["psi_f"] - 1.0) < 0.005


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--flux-harmonics", "5,6"], r"--flux-harmonics order 6 is triplen"),
        (["--flux-harmonics", "1"], r"order 1 is the fundamental"),
        (["--flux-harmonics", "5,x"], r"--flux-harmonics 5,x: give whole orders"),
        (["--cogging-orders", "6,6"], r"--cogging-orders 6,6: an order is given twice"),
        (["--cogging-orders", "6", "--flux-map"], r"--cogging-orders belongs to the linear fit"),
    ],
)
def test_ripple_flags_are_refused_in_one_line(tmp_path, capsys, argv, message):
    from pmsmjax.cli import main

    log = tmp_path / "log.csv"
    log.write_text("time,u_d,u_q,i_d,i_q,omega_m\n0,0,0,0,0,0\n")
    assert main(["identify", str(log), "--pole-pairs", "4", "--out", str(tmp_path / "o"), *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert re.search(message, err) and "\n" not in err, err


def test_cogging_without_a_torque_column_is_refused_before_fitting(tmp_path, capsys, ripple_log):
    from pmsmjax.cli import main
    from pmsmjax.io.logs import write_csv_atomic

    n = 3000
    write_csv_atomic(tmp_path / "log.csv", {k: v[:n] for k, v in ripple_log.items() if k != "T_L"})
    argv = ["identify", str(tmp_path / "log.csv"), "--pole-pairs", "4", "--cogging-orders", "6",
            "--out", str(tmp_path / "o")]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert re.search(r"needs the shaft torque T_L.*log T_L, or drop", err) and "\n" not in err, err
