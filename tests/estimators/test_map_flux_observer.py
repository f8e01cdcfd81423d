"""The reduced-order flux observer on the current-flux relation (``flux-observer``).

References, independent of the code under test: the plant's own angle and flux (the linear dq machine and
the flux-map plant), the power-law saturation model's current map (the auxiliary flux against a finite
difference of the rotated map), central differences for the gradients.

Module: pmsmjax/estimators/map_flux_observer.py.
"""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from pmsmjax import presets
from pmsmjax.analysis.observer_errors import angle_error
from pmsmjax.assemble import assemble, spec_flux_map, spec_scenario
from pmsmjax.drive import PeriodInputs
from pmsmjax.estimators import OBSERVERS
from pmsmjax.estimators.map_flux_observer import (
    MapFluxObserver,
    auxiliary_flux,
)
from pmsmjax.estimators.registry import make_observer
from pmsmjax.frames.three_phase import inverse_park, park
from pmsmjax.io.drive_files import drive_spec
from pmsmjax.machines.syrm_saturation import PowerLawSaturation
from pmsmjax.simulate import simulate
from pmsmjax.spec.validation import ParameterError
from pmsmjax.units import rpm_to_rad_s
from tests.helpers.gradient_check import check_gradient

TS = 1e-4
W1000 = rpm_to_rad_s(1000.0)


def test_registered_for_every_command():
    assert "flux-observer" in OBSERVERS
    est = make_observer("flux-observer", presets.book_motor(), TS)
    assert isinstance(est, MapFluxObserver) and est.flux_map is None
    # the map drives give it the drive file's map (through the I/f start)
    drive = assemble(drive_spec("saturated-ipm"), "pi", estimator="flux-observer")
    assert isinstance(drive.estimator.observer, MapFluxObserver)
    assert drive.estimator.observer.flux_map is not None


def test_auxiliary_flux_is_the_angle_sensitivity_of_the_map():
    """``d/dth [e^{j th} psi(e^{-j th} i)]`` at ``th = 0`` equals ``j psi_a`` (module docstring), on the
    pm-syrm drive's interpolated map (strong cross-saturation), by central differences; ``psi_a`` is
    nowhere near ``psi`` there (the check has teeth)."""
    fm = spec_flux_map(drive_spec("pm-syrm"))
    h = 1e-6
    for i in ((0.0, 10.0), (-20.0, 20.0), (-5.0, -30.0), (8.0, 3.0)):
        i = jnp.asarray(i)

        def rotated(th, i=i):
            return inverse_park(fm(park(i, th))[0], th)  # e^{j th} psi(e^{-j th} i)

        d = (rotated(h) - rotated(-h)) / (2 * h)
        psi, L = fm(i)
        a = auxiliary_flux(psi, L, i)
        assert float(jnp.linalg.norm(a - psi)) > 0.01
        np.testing.assert_allclose(np.asarray(d), [-float(a[1]), float(a[0])], rtol=1e-6, atol=1e-9)


def test_power_law_map_inverts_the_current_map():
    m = PowerLawSaturation(i_f=8.0)
    for i in ((0.0, 0.0), (-20.0, 35.0), (10.0, -5.0)):
        assert np.allclose(m.current(*m.flux(*i)), i, atol=1e-9)


def test_exact_on_a_linear_machine_with_its_exact_model():
    """Book motor at an imposed 1000 r/min, rated q current held in the observer's frame, the observer
    started cold 0.3 rad behind: after 0.1 s the angle is the plant's to 0.01 degree, the speed to 0.1 %
    and the flux estimate the plant's flux ``[L_d i_d + psi_f, L_q i_q]`` to 1e-4 of ``psi_f``."""
    drive = presets.sensorless_drive("flux-observer", mode="current", mechanics="imposed")
    n = 1500
    zeros = jnp.zeros(n)
    xs = PeriodInputs(zeros + W1000, zeros, zeros, zeros + 10.0)
    final, rec = jax.lax.scan(lambda s, x: drive.step(s, x), drive.init(speed_m=W1000, theta_e=0.3), xs)
    err = np.degrees(np.asarray(angle_error(rec.estimate[:, 0], rec.machine.theta_e)))
    assert abs(err[0]) > 15.0 and np.abs(err[-500:]).max() < 0.01
    assert np.abs(np.asarray(rec.estimate[-500:, 1]) - W1000).max() < 1e-3 * W1000
    m = presets.book_motor()
    # the estimate of the last period is at its sampling instant, where the record's plant state is
    i_dq, theta = rec.machine.currents[-1], rec.machine.theta_e[-1]
    psi_true = inverse_park(jnp.stack([m.L_d * i_dq[0] + m.psi_f, m.L_q * i_dq[1]]), theta)
    np.testing.assert_allclose(final.estimator.psi_ab, psi_true, atol=1e-4 * float(m.psi_f))


def test_gradients_of_the_gains():
    """d(mean squared angle error)/d(gain), closed loop at an imposed speed from 0.3 rad off, against
    central differences."""
    drive = presets.sensorless_drive("flux-observer", mode="current", mechanics="imposed")
    n = 300
    zeros = jnp.zeros(n)
    xs = PeriodInputs(zeros + 0.3 * W1000, zeros, zeros, zeros + 5.0)
    names = ("sigma0", "zeta", "k_theta", "k_omega")

    def loss(gains):
        est = eqx.tree_at(lambda e: tuple(getattr(e, k) for k in names), drive.estimator, tuple(gains))
        d = eqx.tree_at(lambda d: d.estimator, drive, est)
        _, rec = jax.lax.scan(lambda s, x: d.step(s, x), d.init(speed_m=0.3 * W1000, theta_e=0.3), xs)
        return jnp.mean(angle_error(rec.estimate[:, 0], rec.machine.theta_e) ** 2)

    g0 = jnp.stack([getattr(drive.estimator, k) for k in names])
    grad = jax.jit(jax.grad(loss))(g0)
    r = check_gradient(
        jax.jit(loss), g0, grad=grad, rel_step=1e-5, step_floor=0.0, rtol=1e-4, atol=1e-16, labels=names
    )
    assert np.all(np.abs(r.fd) > 0.0), r.names


@pytest.mark.parametrize(
    "options, field",
    [
        ({"sigma0": -1.0}, "sigma0"),
        ({"zeta": -0.1}, "zeta"),
        ({"zeta": 5.0, "max_speed_rpm": 20000.0}, "flux gain"),
        ({"bandwidth": 9000.0}, "angle loop"),
        ({"gain": 1.0}, "gain"),
    ],
)
def test_bad_gains_are_refused_in_one_line(options, field):
    with pytest.raises(ParameterError, match=field) as info:
        make_observer("flux-observer", presets.book_motor(), TS, **options)
    assert "\n" not in str(info.value)


#: The start-up of each map drive: speed (r/min), load torque (N m, the rated torque), load time and
#: duration (s), and whether it ends in field weakening. saturated-ipm: 1.5 times its rated speed, in field
#: weakening. pm-syrm: the drive's field weakening (voltage feedback on the d current, floored at the map's
#: MTPV) stalls this reluctance machine near 2900 r/min whatever the estimator (the exact sensor as well):
#: 2800 r/min at the rated torque, the MTPA corner at the voltage limit.
STARTS = {
    "saturated-ipm": (4500.0, 6.175, 0.3, 0.5, True),
    "pm-syrm": (2800.0, 22.4, 0.6, 1.0, False),
}


@pytest.mark.slow
@pytest.mark.parametrize("name", tuple(STARTS))
def test_start_up_to_field_weakening_on_the_map(name):
    """From standstill with the drive file's I/f start and hand-over, through MTPA to the voltage limit
    with the rated load stepped on: after the hand-over (+20 ms) the angle error stays within 3 degrees
    (a few tenths at steady state), the current within the limit throughout; the saturated-ipm drive ends
    in field weakening (its d current below the map's MTPA d current for its q current), the pm-syrm drive
    at its voltage limit."""
    spec = drive_spec(name)
    rpm, load, t_load, duration, weakened = STARTS[name]
    drive = assemble(spec, "pi", estimator="flux-observer")
    tr = simulate(drive, spec_scenario(spec, rpm, load, t_load, duration)).to_numpy()
    t = np.asarray(tr.t)
    c = spec.control
    handover_end = (c["handover_speed_rad_s"] + c["blend_speed_rad_s"]) / c["startup_acceleration_rad_s2"]
    err = np.degrees(np.abs(np.asarray(angle_error(tr.theta_e_est, tr.theta_e))))
    current = np.hypot(tr.i_dq[:, 0], tr.i_dq[:, 1])
    assert current.max() <= 1.01 * float(drive.controller.current_limit)
    assert err[t > handover_end + 0.02].max() < 3.0
    assert err[t > duration - 0.1].max() < 0.3
    assert abs(np.asarray(tr.omega_m)[-1] - rpm_to_rad_s(rpm)) < 0.01 * rpm_to_rad_s(rpm)
    i_d, i_q = tr.i_dq[-1]
    if weakened:
        assert i_d < float(drive.controller.d_axis.mtpa(jnp.asarray(i_q))) - 1.0
    else:
        u_max = spec.inverter["u_dc_v"] / math.sqrt(3.0)
        assert np.hypot(*tr.u_dq_ref[-1]) > 0.85 * u_max
