"""The averaged bridge's voltage error (dead time, device drop) and dead-time compensation, against
independent references.

- The switching-segment bridge (:class:`~pmsmjax.inverters.switching.SwitchingBridge`, which resolves the
  dead windows edge by edge) over steady closed-loop runs at several currents: the period-average phase
  voltages agree to rounding wherever no phase current changes sign within the period; in the periods
  where one does (the ripple's effect), by at most the error's swing ``(4/3) U_dc t_d / Ts``.
- The fundamental of the error at low speed: a square wave of height ``U_dc t_d / Ts`` against the
  current, fundamental ``(4/pi) U_dc t_d / Ts`` (Fourier series of a square wave).
- Narrow pulses and clamped legs against the switching bridge, one period each.
- Compensation: on the switching bridge with dead time, the current loop's tracking error returns to
  the ideal bridge's.
- Without dead time and drop the bridge is the ideal one: its program is the ideal bridge's, and a dead
  time and drop of 0 give the same numbers to rounding.
- Gradient with respect to ``t_d`` against central differences.
"""

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from pmsmjax import ParameterError, Profile, Scenario, simulate
from pmsmjax.controllers.dead_time_compensation import DeadTimeCompensation
from pmsmjax.drive import Drive
from pmsmjax.frames.three_phase import abc_to_alpha_beta
from pmsmjax.inverters import AveragedBridge, SwitchingBridge, VoltageError
from pmsmjax.inverters.base import AbstractBridge
from pmsmjax.machines.base import MachineInput
from pmsmjax.machines.integrate import advance
from pmsmjax.machines.motor import as_float
from pmsmjax.presets.three_phase import book_drive
from pmsmjax.simulate import period_inputs

U_DC = 311.0
TS = 1e-4
T_D = 2e-6
E_DT = U_DC * T_D / TS  # 6.22 V: one leg's dead-time error
SPEED = 100.0 * np.pi / 30.0  # 100 r/min: 6.7 Hz electrical, 1500 periods per cycle
CYCLE = 1500
S3 = np.sqrt(3.0)


def with_bridge(drive, bridge) -> Drive:
    return eqx.tree_at(lambda d: d.bridge, drive, bridge)


def current_drive():
    """The book drive's current loops at an imposed speed."""
    return book_drive(mode="current", mechanics="imposed")


def steady(iq, id_=0.0, periods=CYCLE + 300):
    return Scenario(
        duration_s=periods * TS,
        speed_ref=Profile.constant(SPEED),
        id_ref=Profile.constant(id_),
        iq_ref=Profile.constant(iq),
    )


@eqx.filter_jit
def _period_voltages(bridge, machine, trace_states, duties):
    """``(N, 2)`` period-average stator voltage of ``bridge`` from each recorded state and duty."""
    return jax.vmap(lambda s, d: bridge.advance(machine, s, d, 0.0, TS, 10)[1])(trace_states, duties)


def ab_to_abc(u_ab):
    a, b = u_ab[..., 0], u_ab[..., 1]
    return np.stack([a, -0.5 * a + 0.5 * S3 * b, -0.5 * a - 0.5 * S3 * b], axis=-1)


@eqx.filter_jit
def run_records(drive, scenario):
    """The per-period records (machine state at each period start, duties) of a run from rest."""
    return jax.lax.scan(lambda s, x: drive.step(s, x), drive.init(), period_inputs(scenario, drive.Ts))[1]


def last_cycle(rec):
    return jax.tree.map(lambda x: x[-CYCLE:], rec)


def fundamental(x, theta):
    """Complex amplitude of ``x (N,)`` at the electrical angle ``theta (N,)`` over whole cycles."""
    return 2.0 * np.mean(x * np.exp(-1j * theta))


@pytest.fixture(scope="module")
def switching_runs():
    """Closed-loop runs on the switching bridge with dead time (exact current sign): the last electrical
    cycle's records at (i_d*, i_q*) = (0, 2), (0, 9) and (-3, 6) A."""
    drive = with_bridge(current_drive(), SwitchingBridge(U_DC, dead_time=T_D))
    refs = ((0.0, 2.0), (0.0, 9.0), (-3.0, 6.0))
    return drive, [(ref, last_cycle(run_records(drive, steady(ref[1], ref[0])))) for ref in refs]


def test_averaged_error_matches_the_switching_bridge(switching_runs):
    drive, runs = switching_runs
    averaged = AveragedBridge(U_DC, dead_time=T_D)
    for ref, rec in runs:
        u_sw = ab_to_abc(np.asarray(_period_voltages(drive.bridge, drive.machine, rec.machine, rec.duties)))
        u_avg = ab_to_abc(np.asarray(_period_voltages(averaged, drive.machine, rec.machine, rec.duties)))
        # Periods that start with every phase current above 0.5 A: none changes sign within the period
        # (the ripple at 100 r/min is under 0.3 A: such periods already agree to the sign smoothing's
        # 1e-5), and tanh(0.5 A / 0.05 A) = 1 - 4e-9, so the two models agree to rounding there.
        i_abc = np.asarray(jax.vmap(drive.machine.phase_currents)(rec.machine))
        quiet = (np.abs(i_abc) > 0.5).all(axis=1)[:-1]
        diff = np.abs(u_avg - u_sw)[:-1]
        assert quiet.mean() > 0.25  # a quarter of the periods even at 2 A (the least phase is <= 1 A)
        np.testing.assert_allclose(u_avg[:-1][quiet], u_sw[:-1][quiet], rtol=0, atol=1e-9 * U_DC)
        # a sign change inside the period moves one leg's error by at most 2 E; the phase sees 2/3 of it
        assert diff.max() <= 4.0 / 3.0 * E_DT * (1 + 1e-9)
        # the error is really there: the two bridges differ from the ideal duties' voltage by E
        u_ideal = U_DC * (np.asarray(rec.duties) - np.asarray(rec.duties).mean(axis=1, keepdims=True))
        assert np.abs(u_sw - u_ideal)[:-1][quiet].max() == pytest.approx(4.0 / 3.0 * E_DT, rel=1e-6)
        print(
            f"\nref {ref} A: {100 * quiet.mean():.1f} % of periods agree to rounding; the zero-crossing "
            f"periods differ by up to {diff.max():.2f} V (bound {4 / 3 * E_DT:.2f} V)"
        )


def test_fundamental_loss_is_the_square_wave_s(switching_runs):
    # At 100 r/min the error of each phase is a square wave of height E = U_dc t_d / Ts against its
    # current; its fundamental, (4/pi) E, opposes the current. Each bridge in its own closed-loop run
    # (the error is the period-average voltage minus the ideal U_dc (d - mean d)).
    drive, runs = switching_runs
    averaged = with_bridge(drive, AveragedBridge(U_DC, dead_time=T_D))
    for ref, rec_switching in runs:
        rec_averaged = last_cycle(run_records(averaged, steady(ref[1], ref[0])))
        for bridge, rec in ((drive.bridge, rec_switching), (averaged.bridge, rec_averaged)):
            u = ab_to_abc(np.asarray(_period_voltages(bridge, drive.machine, rec.machine, rec.duties)))
            d = np.asarray(rec.duties)
            error = u - U_DC * (d - d.mean(axis=1, keepdims=True))
            theta = np.unwrap(np.asarray(rec.machine.theta_e))
            i_abc = np.asarray(jax.vmap(drive.machine.phase_currents)(rec.machine))
            e1 = fundamental(error[:, 0], theta)
            i1 = fundamental(i_abc[:, 0], theta)
            loss = -(e1 * np.conj(i1)).real / abs(i1)  # the fundamental's component against the current
            # 1 %: at 2 A the current dwells within 0.05 A of zero for 11-14 % of the cycle (the dead time
            # clamps it there), where the error is neither +E nor -E; 0.1-0.3 % at 6 and 9 A
            tolerance = 0.01 if ref[1] < 5.0 else 0.003
            assert loss == pytest.approx(4.0 / np.pi * E_DT, rel=tolerance), (type(bridge).__name__, ref)


@eqx.filter_jit
def one_period(bridge, machine, state, duties):
    return bridge.advance(machine, state, duties, 0.0, TS, 10)[1]


def _comparable(duties, theta) -> bool:
    """No leg carries a negative current at a duty in (1 - 2 t_d / Ts, 1) (the test's comment says why);
    the phase currents of i_dq = (0, 15 A) at angle ``theta``: ``i_x = -15 sin(theta - x 2 pi / 3)``."""
    i_abc = -15.0 * np.sin(theta - 2 * np.pi / 3 * np.arange(3))
    d = np.asarray(duties)
    return not np.any((i_abc < 0) & (d > 1.0 - 2 * T_D / TS) & (d < 1.0))


PULSE_CASES = [
    (duties, theta)
    for duties in ([0.004, 0.5, 0.9], [0.0, 0.3, 0.7], [1.0, 0.6, 0.015], [0.999, 0.5, 0.2])
    for theta in np.pi / 6 + 2 * np.pi / 3 * np.arange(3)  # between zero crossings
    if _comparable(duties, theta)
]


@pytest.mark.parametrize("duties, theta", PULSE_CASES)
def test_narrow_pulses_and_clamped_legs_match_the_switching_bridge(duties, theta):
    # A pulse narrower than t_d loses only its width (it vanishes); a leg held at 0 or 1 has no edges.
    # The switching bridge cuts a dead window at the period end, so the averaged model's gain for a
    # negative current is its own only for duties below 1 - 2 t_d / Ts (0.96 here): not tested above it.
    # 15 A: every phase carries 7.5 A or more, above the 2.7 A these extreme duties move it in a period.
    machine = current_drive().machine
    duties = jnp.asarray(duties)
    state = machine.initial_state((0.0, 15.0), SPEED, theta)
    i_abc = np.asarray(machine.phase_currents(state))
    np.testing.assert_allclose(i_abc, -15.0 * np.sin(theta - 2 * np.pi / 3 * np.arange(3)), atol=1e-9)
    end = SwitchingBridge(U_DC).advance(machine, state, duties, 0.0, TS, 10)[0]
    assert np.all(np.sign(machine.phase_currents(end)) == np.sign(i_abc))  # no sign change in the period
    u_sw = one_period(SwitchingBridge(U_DC, dead_time=T_D, device_drop=1.2), machine, state, duties)
    u_avg = one_period(AveragedBridge(U_DC, dead_time=T_D, device_drop=1.2), machine, state, duties)
    np.testing.assert_allclose(u_avg, u_sw, rtol=0, atol=1e-9 * U_DC)


def test_compensation_restores_the_current_tracking():
    # Plant: the switching bridge with dead time. The dead time leaves a tracking error (the current
    # flattens at each zero crossing: 6th harmonic in dq, 5th and 7th in the phases); the compensation,
    # knowing t_d, takes most of it away: 94 % of the RMS tracking error with its sign smoothed over
    # 0.1 A (2.5 % of the current; 99 % over 0.02 A, 68 % over 0.5 A, which blurs the correction near
    # the zero crossings that cause the error).
    base = current_drive()
    compensated = eqx.tree_at(
        lambda d: d.controller.dead_time_compensation,
        base,
        DeadTimeCompensation(VoltageError(T_D, 0.0, 0.1)),
        is_leaf=lambda x: x is None,
    )
    scenario = steady(4.0)
    rms = {}
    for name, drive, bridge in (
        ("ideal", base, SwitchingBridge(U_DC)),
        ("dead time", base, SwitchingBridge(U_DC, dead_time=T_D)),
        ("compensated", compensated, SwitchingBridge(U_DC, dead_time=T_D)),
    ):
        rec = last_cycle(run_records(with_bridge(drive, bridge), scenario))
        i_dq = np.asarray(jax.vmap(drive.machine.currents_dq)(rec.machine))
        theta = np.unwrap(np.asarray(rec.machine.theta_e))
        i_a = np.asarray(jax.vmap(drive.machine.phase_currents)(rec.machine))[:, 0]
        harmonics = i_a - (fundamental(i_a, theta) * np.exp(1j * theta)).real
        rms[name] = (
            np.sqrt(np.mean(np.sum((i_dq - np.asarray(rec.i_dq_ref)) ** 2, axis=1))),
            np.sqrt(np.mean(harmonics**2)),
            abs(fundamental(i_a, theta)),
        )
    print("\n" + "\n".join(f"{k}: tracking RMS {v[0]:.4f} A, harmonics RMS {v[1]:.4f} A, fundamental "
                             f"{v[2]:.4f} A" for k, v in rms.items()))  # fmt: skip
    caused = rms["dead time"][0] - rms["ideal"][0]
    assert caused > 0.05  # the dead time does disturb the loop
    assert rms["compensated"][0] - rms["ideal"][0] < 0.1 * caused
    assert rms["compensated"][1] < 0.1 * rms["dead time"][1]
    # the fundamental: the integrators do not hold the 4 A peak against the dead time (the loss comes
    # and goes with the sign pattern, not a constant in dq); compensated, it is the ideal bridge's again
    shortfall = {k: abs(v[2] - rms["ideal"][2]) for k, v in rms.items()}
    assert shortfall["dead time"] > 0.05
    assert shortfall["compensated"] < 0.1 * shortfall["dead time"]


class IdealBridge(AbstractBridge):
    """The averaged bridge without any voltage error, written out from its formula."""

    u_dc: jax.Array

    def advance(self, machine, state, duties, load_torque, Ts, n_substeps):
        u_ab = abc_to_alpha_beta(self.u_dc * (duties - jnp.mean(duties, axis=-1, keepdims=True)))
        return advance(machine, state, MachineInput(u_ab, load_torque, "stator"), Ts, n_substeps), u_ab


def test_without_dead_time_the_bridge_is_the_ideal_one():
    drive = book_drive()
    x = jax.tree.map(lambda v: v[0], period_inputs(steady(3.0), drive.Ts))
    step_jaxpr = lambda bridge: str(jax.make_jaxpr(with_bridge(drive, bridge).step)(drive.init(), x))
    assert step_jaxpr(AveragedBridge(U_DC)) == step_jaxpr(IdealBridge(as_float(U_DC)))
    scenario = Scenario(
        duration_s=0.02, speed_ref=Profile.constant(50.0), load_torque=Profile.step(0.01, 0, 5)
    )
    ideal = simulate(drive, scenario)
    zero = simulate(with_bridge(drive, AveragedBridge(U_DC, dead_time=0.0, device_drop=0.0)), scenario)
    # An explicit zero error is a different program (its terms multiply by zero), compiled separately:
    # equal to rounding, not bit for bit (XLA:CPU may contract or order the same sums differently).
    for name in ("i_dq", "omega_m", "duties"):
        np.testing.assert_allclose(
            np.asarray(getattr(zero, name)), np.asarray(getattr(ideal, name)), rtol=1e-12, atol=1e-12
        )


@pytest.mark.slow  # 7 s: compiling the reverse-mode scan
def test_gradient_with_respect_to_dead_time_matches_differences():
    drive = with_bridge(current_drive(), AveragedBridge(U_DC, dead_time=T_D, sign_smoothing=0.5))
    scenario = steady(3.0, periods=150)

    def mean_iq(t_d):
        d = eqx.tree_at(lambda d: d.bridge.voltage_error.dead_time, drive, t_d)
        rec = run_records(d, scenario)
        return jnp.mean(jax.vmap(d.machine.currents_dq)(rec.machine)[-100:, 1] ** 2)

    value_and_grad = jax.jit(jax.value_and_grad(mean_iq))  # one program for the gradient and the values
    grad = float(value_and_grad(jnp.asarray(T_D))[1])
    h = 1e-8
    upper, lower = (float(value_and_grad(jnp.asarray(T_D + dt))[0]) for dt in (h, -h))
    numeric = (upper - lower) / (2 * h)
    assert np.isfinite(grad)
    assert grad == pytest.approx(numeric, rel=1e-5)


def test_dead_time_must_fit_the_period():
    with pytest.raises(ParameterError, match="AveragedBridge.dead_time = 6e-05 s is not below half"):
        dataclasses.replace(book_drive(), bridge=AveragedBridge(U_DC, dead_time=60e-6))
    with pytest.raises(ParameterError, match="device_drop"):
        AveragedBridge(U_DC, device_drop=-1.0)
