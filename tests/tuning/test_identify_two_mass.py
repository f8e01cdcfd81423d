"""A compliant shaft identified from speed steps (tuning/identify/two_mass_fit.py, ``identify --two-mass``).

The log is ``tuning.identify.shaft_reference_log``: SciPy's DOP853 integrates the warm dq machine (60 degC,
R and psi_f off their 20 degC values), its thermal node and the two-mass mechanics (motor 5e-4 kg m^2, load
1e-3 kg m^2, 300 N m/rad, 0.02 N m s/rad: resonance 151.0 Hz, anti-resonance 87.2 Hz) under a speed PI
and the heat run's current loop, which read faulty current sensors and a turned encoder behind an inverter
with dead time; only the motor speed is logged (50 mrad/s noise).

The currents are per ampere as sensor a reads it (gain 0.99), so the inertias, the stiffness and the damping
come out 1 % low; the frequencies are ratios and do not.
"""

import math

import numpy as np
import pytest

from pmsmjax.spec.validation import ParameterError
from tuning.identify.heat_run_log import SENSORS
from tuning.identify.sensor_errors import corrected_columns, identify_sensor_errors, sensor_log_from_columns
from tuning.identify.shaft_reference_log import SHAFT, resonance_hz, shaft_log
from tuning.identify.stator_stage import _narrow_temperature
from tuning.identify.two_mass_fit import fit_two_mass, two_mass_from_columns

G_A = SENSORS["current_gain"][0]


@pytest.fixture(scope="module")
def log():
    return shaft_log()


@pytest.fixture(scope="module")
def fitted(log):
    cols = {k: v for k, v in log.items() if k != "temperature_c"}  # a still temperature (the stage's rule)
    assert _narrow_temperature(log["temperature_c"]) is not None
    slog, c = sensor_log_from_columns(cols)
    errors = identify_sensor_errors(slog, dead_time=True)
    corrected = corrected_columns(c, errors)
    return errors, corrected, two_mass_from_columns(corrected, errors.machine, None, 4, 20.0, slog.segments)


def test_the_shaft_and_its_resonance(fitted):
    """Measured: resonance 150.97 Hz (-0.01 %), anti-resonance 87.10 Hz (-0.09 %); J_m -0.14 %, J_L +0.1 %,
    K -0.08 %, D -0.4 % (per sensor-a ampere)."""
    shaft = fitted[2]
    assert abs(shaft["resonance_hz"]["value"] / resonance_hz() - 1.0) < 0.02
    assert abs(shaft["resonance_hz"]["value"] / resonance_hz() - 1.0) < 0.002  # what it measures
    anti = math.sqrt(SHAFT["K"] / SHAFT["J_L"]) / (2 * math.pi)
    assert abs(shaft["anti_resonance_hz"]["value"] / anti - 1.0) < 0.01
    for name in ("J_m", "J_L", "K", "D"):
        e = shaft[name]
        assert e["identifiable"], name
        assert abs(e["value"] / (G_A * SHAFT[name]) - 1.0) < 0.02, (name, e)
        assert e["ci95"][0] < e["value"] < e["ci95"][1]
    assert shaft["residual_rms_rad_s"] < 0.06  # the speed noise, 0.05 rad/s


def test_a_rigid_model_of_the_same_log_is_wrong(fitted, log):
    """A rigid shaft is the two-mass fit with a stiff spring: started there and held, it leaves the ringing
    in the residual: measured 1.09 rad/s, 22x the speed noise."""
    from tuning.identify.two_mass_fit import TwoMassProblem

    _, corrected, shaft = fitted
    from tuning.identify.cogging_fit import electromagnetic_torque

    torque = electromagnetic_torque(corrected, fitted[0].machine, 4, 20.0)
    pr = TwoMassProblem(corrected["time"], corrected["omega_m"], torque, np.array([0, log["time"].size]), 500)
    j = shaft["J_m"]["value"] + shaft["J_L"]["value"]
    rigid = np.array([*np.log([0.5 * j, 0.5 * j, 1e7, 1e2, shaft["B"]["value"]]), 0.0])
    assert float(np.sqrt(np.mean(pr.residuals(rigid) ** 2))) > 10 * shaft["residual_rms_rad_s"]


def test_a_constant_speed_is_refused():
    t = np.arange(2000) * 1e-4
    with pytest.raises(ParameterError, match=r"--two-mass needs a run with speed steps"):
        fit_two_mass(t, np.full(t.size, 10.0), np.zeros(t.size))


PRIOR = (
    "[motor]\nR = 0.5\nL_d = 0.002\nL_q = 0.003\npsi_f = 0.08\npole_pairs = 4\nJ = 0.001\nB = 0.0001\n"
    '[sensor]\nkind = "encoder"\nlines = 2500\n'
)


@pytest.mark.slow
def test_identify_two_mass_writes_mechanics(log, tmp_path, capsys):
    """``identify --dead-time --two-mass`` on the CSV: the still temperature noted, the shaft printed with
    its intervals and motor.toml's [mechanics] and [motor] J, B read back by the drive-file reader."""
    from pmsmjax.cli import main
    from pmsmjax.io.drive_files import drive_spec
    from pmsmjax.io.logs import write_csv_atomic
    from pmsmjax.machines.shaft import resonance_rad_s

    write_csv_atomic(tmp_path / "log.csv", log)
    (tmp_path / "prior.toml").write_text(PRIOR)
    out = tmp_path / "id"
    argv = ["identify", str(tmp_path / "log.csv"), "--dead-time", "--two-mass", "--motor",
            str(tmp_path / "prior.toml"), "--out", str(out), "--load", "none", "--no-figures"]  # fmt: skip
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "resonance" in text and "without temperature coefficients" in text
    spec = drive_spec(str(out / "motor.toml"))
    m = spec.mechanics
    f = resonance_rad_s(spec.motor["J"], m["load_inertia"], m["shaft_stiffness_nm_per_rad"]) / (2 * math.pi)
    assert abs(f / resonance_hz() - 1.0) < 0.02
    assert spec.motor["J"] == pytest.approx(G_A * SHAFT["J_m"], rel=0.02)
