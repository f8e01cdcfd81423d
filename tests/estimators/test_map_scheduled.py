"""Back-EMF observers and the EKF on a flux map: the constant model's steady angle error and the
map-scheduled model's.

References, independent of the code under test: the steady-state rotor-frame voltage equation on the
map's interpolant (the constant model's error as a fixed point, worked in NumPy), and the plant's true
angle in sensorless runs on the saturated-ipm map's plant at an imposed speed.

Module: pmsmjax/estimators/map_scheduled.py.
"""

import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest

from pmsmjax import presets
from pmsmjax.analysis.observer_errors import angle_error
from pmsmjax.assemble import spec_drive, spec_flux_map, spec_motor
from pmsmjax.estimators.map_scheduled import (
    SECANT_FLOOR_A,
    constant_model_angle_error,
    map_model,
    map_scheduled,
)
from pmsmjax.io.drive_files import drive_spec
from pmsmjax.io.flux_map_files import read_flux_map
from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.simulate import simulate
from pmsmjax.units import rpm_to_rad_s

SPEC = drive_spec("saturated-ipm")
GRID = read_flux_map(SPEC.motor["flux_map"])
MOTOR = spec_motor(SPEC)
SPEED = rpm_to_rad_s(1000.0)
I_Q = 10.0  # A, the rated current (i_d = 0 in the estimated frame)


def test_map_model_reproduces_the_maps_flux():
    """The active-flux model ``psi = [psi_f + L_d i_d, L_q i_q]`` equals the map's flux at the point."""
    fm = spec_flux_map(SPEC)
    for i in ((0.0, 10.0), (-8.0, 4.0), (-3.0, -12.0), (2.0, 0.2)):
        m = map_model(fm, MOTOR, jnp.asarray(i))
        psi, L = GRID.at(*i)
        assert float(m.psi_f + m.L_d * i[0]) == pytest.approx(psi[0], rel=1e-12)
        expected_q = L[1, 1] * i[1] if abs(i[1]) < SECANT_FLOOR_A else psi[1]
        assert float(m.L_q * i[1]) == pytest.approx(expected_q, rel=1e-12)


@pytest.mark.slow
@pytest.mark.parametrize("method", ("smo", "dq-smo", "ekf"))
def test_constant_model_error_matches_voltage_equation_and_map_removes_it(method):
    """Rated q current at 1000 r/min (imposed), the observers started 0.3 rad off; steady error = mean
    of the last 100 ms. The EKF reads part of the flux mismatch as a speed error (1.5 % here), which
    moves its angle up to 1.5 deg off the voltage-equation prediction; the SMOs are within 0.1 deg."""
    predicted, _ = constant_model_angle_error(GRID, float(MOTOR.L_q), (0.0, I_Q))
    assert math.degrees(predicted) > 15.0
    drive = presets.with_observer(
        spec_drive(SPEC, mode="current", mechanics="imposed"), method, MOTOR, None, startup=False
    )
    scheduled = eqx.tree_at(lambda d: d.estimator, drive, map_scheduled(drive.estimator, spec_flux_map(SPEC)))
    sc = Scenario(0.3, speed_ref=Profile.constant(SPEED), iq_ref=Profile.step(0.05, 0.0, I_Q))
    errors = {}
    for name, d in (("constant", drive), ("map", scheduled)):
        tr = simulate(d, sc, initial_state=d.init(speed_m=SPEED, theta_e=0.3))
        errors[name] = float(np.mean(np.asarray(angle_error(tr.theta_e_est, tr.theta_e))[-1000:]))
    tolerance = 1.5 if method == "ekf" else 0.1
    assert abs(math.degrees(errors["constant"] - predicted)) < tolerance
    assert abs(math.degrees(errors["map"])) < 0.1


def test_map_aware_wiring_wraps_observer_inside_startup_and_refuses_files_without_a_map():
    from pmsmjax import ParameterError
    from pmsmjax.assemble import startup_options, with_map_aware_estimator
    from pmsmjax.estimators.hfi_cross_saturation import CrossSaturationCompensated
    from pmsmjax.estimators.map_angle_corrected import MapAngleCorrected

    base = spec_drive(SPEC)
    ekf = presets.with_observer(base, "ekf", MOTOR, startup_options=startup_options(SPEC))
    wrapped = with_map_aware_estimator(SPEC, ekf)
    assert isinstance(wrapped.estimator.observer, MapAngleCorrected)
    hfi_model = eqx.tree_at(lambda m: (m.L_d, m.L_q), MOTOR, (5e-3, 12e-3))
    hfi = presets.with_observer(base, "hfi-rotating", hfi_model, startup=False)
    assert isinstance(with_map_aware_estimator(SPEC, hfi).estimator, CrossSaturationCompensated)
    with pytest.raises(ParameterError, match="flux_map"):
        with_map_aware_estimator(drive_spec("book"), presets.sensorless_drive("ekf"))
    with pytest.raises(ParameterError, match="fundamental-model observers"):
        map_scheduled(hfi.estimator, spec_flux_map(SPEC))
