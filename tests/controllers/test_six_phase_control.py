"""Six-phase vector control (BOOK.md chapter 9) on the six-phase book scenario (1000 r/min, 10 N m at 0.2 s).

Must-show: every scheme (conventional, VSD, double dq, stationary-frame PR) runs the scenario; the VSD
scheme's z1-z2 loops drive the z1-z2 current of a set-to-set resistance unbalance to zero (the
conventional scheme leaves it); double dq and VSD designed equivalently (book 9.5) give the same
response within 1 %, and not without the cross-coupling compensation; ``jax.grad`` through the closed
loop matches central differences within 1e-4; a ``vmap`` batch equals single runs.

Independent references: the three-phase book drive (same torque constant, same loop designs: its speed
response is the one the six-phase drive must reproduce with z1-z2 at zero), the conventional scheme's
open-loop z1-z2 current, and finite differences.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from pmsmjax import Drive, ParameterError, simulate
from pmsmjax.analysis.speed_step_summary import speed_step_summary
from pmsmjax.controllers.six_phase import SixPhaseFOC, double_dq_design
from pmsmjax.frames.multiphase import SIX_PHASE, vsd
from pmsmjax.presets.six_phase import SIX_PHASE_CONTROLS, six_phase_drive, six_phase_motor
from pmsmjax.presets.three_phase import book_drive, book_scenario
from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.units import rad_s_to_rpm

SCHEMES = tuple(SIX_PHASE_CONTROLS)
UNBALANCE = (1.0, 1.0, 1.0, 1.5, 1.5, 1.5)  # set UVW's resistance 1.5 times set ABC's


def z_magnitude(trace):
    i_z = np.asarray(vsd(trace.i_abc, SIX_PHASE))[:, 2:4]
    return np.hypot(i_z[:, 0], i_z[:, 1])


@pytest.fixture(scope="module")
def balanced():
    scenario = book_scenario()
    return {name: simulate(six_phase_drive(control=name), scenario) for name in SCHEMES}


@pytest.fixture(scope="module")
def unbalanced():
    scenario = book_scenario()
    return {
        name: simulate(six_phase_drive(control=name, pwm="double-zs", resistance_scale=UNBALANCE), scenario)
        for name in SCHEMES
    }


@pytest.mark.parametrize("scheme", SCHEMES)
def test_each_scheme_runs_the_book_scenario(balanced, scheme):
    trace = balanced[scheme]
    m = speed_step_summary(trace, load_time_s=0.2, current_limit_a=15.0)
    assert abs(m["final_speed_rpm"] - 1000.0) < 1.0
    assert abs(float(rad_s_to_rpm(trace.omega_m[1999])) - 1000.0) < 1.0  # settled before the load step
    assert 150.0 < m["speed_dip_rpm"] < 350.0 and m["recovery_time_s"] < 0.15
    assert m["current_limit_respected"] and m["overshoot_pct"] < 1.0
    assert np.max(z_magnitude(trace)) < 1e-9  # balanced machine, four-vector SVPWM: no z1-z2 current
    # The rewound machine has the book motor's torque constant and the same loop designs: the three-phase
    # book drive's speed response, to within 1 % of the reference.
    three = simulate(book_drive(), book_scenario()) if scheme == SCHEMES[0] else None
    if three is not None:
        assert np.max(np.abs(rad_s_to_rpm(trace.omega_m - three.omega_m))) < 10.0


@pytest.mark.parametrize("scheme", SCHEMES)
def test_z_loops_remove_the_z_current_of_a_resistance_unbalance(unbalanced, scheme):
    z = z_magnitude(unbalanced[scheme])
    tail = z[-500:]  # the last 50 ms, 10 N m at 1000 r/min
    if scheme == "conventional":
        # z open loop: the unbalance voltage (R_UVW - R_ABC)/2 i_ab drives (R + j w L_ls)^-1 of it.
        assert np.min(tail) > 1.5
    else:
        assert np.max(tail) < 0.01, scheme
        assert np.max(tail) < 0.01 * np.min(z_magnitude(unbalanced["conventional"])[-500:])


def test_double_dq_and_vsd_designed_equivalently_give_the_same_response(balanced, unbalanced):
    for runs in (balanced, unbalanced):
        v, d = runs["vsd"], runs["double-dq"]
        assert np.max(np.abs(d.omega_m - v.omega_m)) < 0.01 * np.max(np.abs(v.omega_m))
        assert np.max(np.abs(d.i_abc - v.i_abc)) < 0.01 * np.max(np.abs(v.i_abc))
    # Without the cross-coupling compensation the double-dq loops are another controller: its common-mode
    # gain is the set's self gain a_c (L_d + L_ls)/2, about half the VSD loop's a_c L_d.
    drive = six_phase_drive(control="double-dq")
    plain = eqx.tree_at(
        lambda d: d.controller.current,
        drive,
        double_dq_design(six_phase_motor(), 1100.0, cross_coupling=False),
    )
    p = simulate(plain, book_scenario())
    assert np.max(np.abs(p.i_dq - balanced["vsd"].i_dq)) > 0.1 * np.max(np.abs(balanced["vsd"].i_dq))


def short_scenario():
    return Scenario(0.02, speed_ref=Profile.constant(50.0), load_torque=Profile.step(0.01, 0.0, 3.0))


GAINS = (
    lambda d: d.controller.speed.kp,
    lambda d: d.controller.current.dq.kp_q,
    lambda d: d.controller.current.z.kp,
    lambda d: d.controller.current.z.ki,
)


def with_gains(drive, x):
    """``drive`` with the gains of :data:`GAINS` scaled by ``1 + x`` (x: (4,))."""
    return eqx.tree_at(
        lambda d: [g(d) for g in GAINS], drive, [g(drive) * (1.0 + x[k]) for k, g in enumerate(GAINS)]
    )


def test_gradient_through_the_six_phase_loop_matches_central_differences():
    drive = six_phase_drive(control="vsd", pwm="double-zs", resistance_scale=UNBALANCE, n_substeps=2)
    scenario = short_scenario()

    @jax.jit
    def loss(x):
        tr = simulate(with_gains(drive, x), scenario)
        i_z = vsd(tr.i_abc, SIX_PHASE)[:, 2:4]
        return jnp.mean((tr.speed_ref - tr.omega_m) ** 2) * 1e-2 + jnp.mean(i_z**2) * 1e2

    x0 = jnp.zeros(4)
    g = np.asarray(jax.grad(loss)(x0))
    h = 1e-5
    fd = np.array([(loss(x0.at[k].add(h)) - loss(x0.at[k].add(-h))) / (2 * h) for k in range(4)])
    assert np.all(np.abs(g) > 1e-8)  # every gain moves the loss
    np.testing.assert_allclose(g, fd, rtol=1e-4)


def test_vmap_batch_equals_single_runs():
    base = six_phase_drive(control="double-dq", pwm="decoupled", resistance_scale=UNBALANCE)
    scenario = short_scenario()
    drives = [
        eqx.tree_at(
            lambda d: (d.controller.current.kc_d, d.machine.motor.R),
            base,
            (base.controller.current.kc_d * f, base.machine.motor.R * r),
        )
        for f, r in ((1.0, 1.0), (0.5, 1.2), (1.5, 0.8))
    ]
    batch = jax.tree.map(lambda *xs: jnp.stack(xs), *drives)
    batched = jax.vmap(lambda d: simulate(d, scenario))(batch)
    for k, d in enumerate(drives):
        single = simulate(d, scenario)
        np.testing.assert_allclose(batched.i_abc[k], single.i_abc, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(batched.omega_m[k], single.omega_m, rtol=1e-12, atol=1e-10)


def test_six_phase_controller_checks():
    with pytest.raises(ParameterError, match="six-phase motor"):
        SixPhaseFOC(
            model=book_drive().controller.model,
            speed=book_drive().controller.speed,
            current=six_phase_drive().controller.current,
            current_limit=15.0,
        )
    three, six = book_drive(), six_phase_drive()
    with pytest.raises(ParameterError, match="modulator drives 6 legs"):
        Drive(three.machine, three.controller, six.modulator, three.bridge)
    with pytest.raises(ParameterError, match="bridge has 3 legs"):
        Drive(six.machine, six.controller, six.modulator, three.bridge)
    with pytest.raises(ParameterError, match="six-phase control must be one of"):
        six_phase_drive(control="dtc")
    with pytest.raises(ParameterError, match="six-phase pwm must be one of"):
        six_phase_drive(pwm="svpwm")
