"""Magnet polarity detection (pmsmjax/estimators/polarity.py) on the saturated salient book machine.

The wrapped estimator here is a stand-in for an HF injection estimator: the true angle plus pi on half of
the cases (the modulo-pi ambiguity) plus a 3 degree error. Checks:

- from 24 initial angles around the circle, the drive (speed step to 50 rad/s at t = 0) ends with the angle
  error at the stand-in's 3 degrees, never pi, and running forward at the reference;
- the measured secant inductances match the flux map's, ``(psi_d(+-I) - psi_d(0)) / (+-I)`` integrated
  here by quadrature; on the linear machine they are equal (no polarity information without saturation);
- a 50 % resistance error in the detector's model leaves every decision right;
- contrast: without detection, a start with the estimate off by pi runs away backwards.
"""

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import quad

from pmsmjax.estimators.base import AbstractEstimator
from pmsmjax.estimators.polarity import polarity_detector
from pmsmjax.frames.three_phase import wrap_angle
from pmsmjax.machines import PMSMdq
from pmsmjax.machines.saturation import saturated_machine
from pmsmjax.presets.three_phase import book_drive, book_motor
from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.signals import Estimate
from pmsmjax.simulate import period_inputs, simulate

SPEED = 50.0  # rad/s mechanical
BIAS = np.deg2rad(3.0)
ANGLES = np.arange(24) * 2.0 * np.pi / 24.0
OFFSETS = np.where(np.arange(24) % 2 == 1, np.pi, 0.0) + BIAS
SCENARIO = Scenario(duration_s=0.15, speed_ref=Profile.constant(SPEED), load_torque=Profile.constant(0.0))


class ModuloPiStandIn(AbstractEstimator):
    """The true angle plus ``offset`` (rad): an estimator that knows the d axis only modulo pi."""

    offset: jax.Array

    def init(self, sample):
        return None

    def step(self, state, sample, Ts):
        return None, Estimate(wrap_angle(sample.sensor_theta_e + self.offset), sample.sensor_omega_m)


@pytest.fixture(scope="module")
def drive():
    motor = book_motor(salient=True)
    detector = polarity_detector(ModuloPiStandIn(jnp.asarray(0.0)), motor.R)
    return eqx.tree_at(
        lambda d: (d.machine, d.estimator), book_drive(motor), (saturated_machine(motor), detector)
    )


def _with(drive, offset):
    return eqx.tree_at(lambda d: d.estimator.observer.offset, drive, jnp.asarray(offset))


def test_right_polarity_from_24_angles(drive):
    def run(theta0, offset):
        d = _with(drive, offset)
        tr = simulate(d, SCENARIO, initial_state=d.init(theta_e=theta0))
        return tr.t, tr.omega_m, wrap_angle(tr.theta_e_est - tr.theta_e)

    t, w, err = jax.jit(jax.vmap(run))(jnp.asarray(ANGLES), jnp.asarray(OFFSETS))
    t, w, err = np.asarray(t[0]), np.asarray(w), np.asarray(err)
    after = t >= float(drive.estimator.decision_time)
    np.testing.assert_allclose(err[:, after], BIAS, atol=1e-9)  # flipped where needed, kept elsewhere
    assert np.all(np.abs(err[1::2, ~after]) > 3.0)  # before the decision the odd cases were off by pi
    assert w.min() > -1.0  # never runs backwards (a few tenths of rad/s of settling at most)
    assert np.all(np.abs(w[:, -1] - SPEED) < 0.15 * SPEED)


def _secants(drive, theta0, offset):
    d = _with(drive, offset)
    state, _ = jax.lax.scan(lambda s, x: d.step(s, x), d.init(theta_e=theta0), period_inputs(SCENARIO, d.Ts))
    return d.estimator.secant_inductances(state.estimator)


def test_secant_inductances_against_flux_map(drive):
    m = book_motor(salient=True)
    sat = drive.machine.saturation
    a, i_s, L_d, i_p = (
        float(x) for x in (sat.depth, sat.current_scale, m.L_d, drive.estimator.pulse_current)
    )
    psi = lambda i: quad(lambda x: L_d * (1.0 - a * np.tanh(x / i_s)), 0.0, i)[0]
    L_plus, L_minus = psi(i_p) / i_p, psi(-i_p) / -i_p  # along the magnet's +d and -d
    measured = np.asarray(jax.jit(jax.vmap(lambda t, o: _secants(drive, t, o)))(ANGLES[:2], OFFSETS[:2]))
    # case 0: estimate on +d, case 1: estimate on -d (the pulses swap)
    np.testing.assert_allclose(measured[0], [L_plus, L_minus], rtol=0.02)
    np.testing.assert_allclose(measured[1], [L_minus, L_plus], rtol=0.02)
    assert L_minus / L_plus > 1.25

    linear = eqx.tree_at(lambda d: d.machine, drive, PMSMdq(m))
    lin = np.asarray(jax.jit(lambda t, o: _secants(linear, t, o))(ANGLES[0], OFFSETS[0]))
    np.testing.assert_allclose(lin, L_d, rtol=0.01)  # both equal to L_d: nothing to tell north from south
    assert abs(lin[0] - lin[1]) < 0.05 * abs(L_plus - L_minus)


def test_resistance_error_keeps_decision(drive):
    bad = eqx.tree_at(lambda d: d.estimator.R, drive, drive.estimator.R * 1.5)
    L = np.asarray(jax.jit(jax.vmap(lambda t, o: _secants(bad, t, o)))(ANGLES[:6], OFFSETS[:6]))
    wrong = OFFSETS[:6] > 1.0
    np.testing.assert_array_equal(L[:, 0] > L[:, 1], wrong)


def test_without_detection_runs_backwards(drive):
    blind = eqx.tree_at(lambda d: d.estimator, drive, ModuloPiStandIn(jnp.asarray(np.pi + BIAS)))
    tr = simulate(blind, SCENARIO, initial_state=blind.init(theta_e=0.5))
    assert float(tr.omega_m[-1]) < -2.0 * SPEED


def test_with_rotating_injection_from_24_angles(drive):
    """The real modulo-pi estimator (rotating HF injection, locking to the d axis nearest its start angle
    0, i.e. to the wrong pole for half of the initial angles): after detection every start has the right
    polarity, and a speed step at 80 ms runs forward."""
    from pmsmjax.estimators.hfi_rotating import hfi_rotating_design

    hfi = hfi_rotating_design(drive.machine.motor, drive.Ts)
    d = eqx.tree_at(lambda d: d.estimator.observer, drive, hfi)
    sc = Scenario(duration_s=0.2, speed_ref=Profile.step(0.08, 0.0, 30.0), load_torque=Profile.constant(0.0))

    def run(theta0):
        tr = simulate(d, sc, initial_state=d.init(theta_e=theta0))
        return tr.t, tr.omega_m, wrap_angle(tr.theta_e_est - tr.theta_e)

    t, w, err = jax.jit(jax.vmap(run))(jnp.asarray(ANGLES))
    t, w, err = np.asarray(t[0]), np.asarray(w), np.rad2deg(np.asarray(err))
    k_lock = np.searchsorted(t, float(d.estimator.settle_time)) - 1
    wrong_pole = np.abs(err[:, k_lock]) > 90.0
    assert 8 <= wrong_pole.sum() <= 16  # the injection alone locks to the wrong pole for about half
    after = t >= float(d.estimator.decision_time) + float(d.estimator.release_time)
    assert np.abs(err[:, after]).max() < 10.0
    # standstill hold on the injection speed estimate: a few rad/s of wander, never a run backwards
    assert np.all(np.abs(w[:, -1] - 30.0) < 1.5) and w.min() > -0.1 * 30.0


def test_sigmoid_decision_surrogate(drive):
    """The smooth surrogate agrees with the comparator away from a tie and has the sigmoid's gradient."""
    from pmsmjax.estimators.polarity import PolarityState

    det = dataclasses.replace(drive.estimator, decision="sigmoid")
    t_dec = float(det.decision_time)

    def flip(L_plus, L_minus, d=det):
        # state with unit current changes, so the secant inductances are the fluxes
        s = PolarityState(
            None, jnp.asarray(t_dec), jnp.asarray(0.0), jnp.stack([L_plus, L_minus]), jnp.ones(2)
        )
        return d.flip(s, t_dec)

    exact = drive.estimator
    for Lp, Lm in [(4.6e-3, 5.9e-3), (5.9e-3, 4.6e-3)]:
        assert abs(float(flip(Lp, Lm)) - float(flip(Lp, Lm, exact))) < 1e-5
    scale = float(det.decision_scale)
    g = float(jax.grad(flip)(5.0e-3, 5.0e-3))  # at a tie: pi sigmoid'(0) / scale
    assert abs(g - np.pi * 0.25 / scale) < 1e-9 * abs(g)
    assert (
        float(flip(5.0e-3, 5.0e-3, exact)) == 0.0
        and float(jax.grad(lambda a: flip(a, 5.0e-3, exact))(5.0e-3)) == 0
    )
