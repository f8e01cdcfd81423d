"""Six-phase (the book, ch. 9) and five-phase (chapter 10) vector control on the book scenario
(1000 r/min, 10 N m at 0.2 s).

Shown: every scheme of either machine (conventional, VSD, stationary-frame PR; six phases also double
dq) runs the scenario with the three-phase book drive's speed response and ``i_q = (T_L + B w) / K_t`` in
steady state. Six phases: the VSD scheme's z1-z2 loops drive the z1-z2 current of a set-to-set resistance
unbalance to zero (the conventional scheme leaves it); double dq and VSD designed equivalently (book 9.5)
give the same response within 1 %, and not without the cross-coupling compensation. Five phases: the x-y
loops (PI in the ``3 theta_e`` frame) drive the x-y current of a third-harmonic back-EMF to zero, where the
conventional scheme leaves amperes; a phase resistance unbalance's x-y current (at +-w_e) is removed by
the x-y PR and, measured and stated, not by the ``3 theta_e`` PI. For both, ``jax.grad`` through the closed
loop matches central differences within 1e-4 and a ``vmap`` batch equals single runs.

Independent references: the three-phase book drive (both rewinds have its torque constant, 1.5 p_n psi_f =
1.0962 N m/A, and the same loop designs, so its speed response is the one they must reproduce with the
second plane at zero), the conventional scheme's open-loop z1-z2 current, the x-y current a third-harmonic
back-EMF drives through ``R + j 3 w_e L_ls`` with the x-y voltage at zero (computed here), and finite
differences.
"""

import dataclasses
from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from pmsmjax import Drive, ParameterError, simulate
from pmsmjax.analysis.speed_step_summary import speed_step_summary
from pmsmjax.controllers.multiphase import MultiPhaseFOC
from pmsmjax.controllers.multiphase_design import double_dq_design
from pmsmjax.frames.multiphase import FIVE_PHASE, SIX_PHASE, PhaseLayout, vsd
from pmsmjax.presets.five_phase import (
    FIVE_PHASE_CONTROLS,
    FIVE_PHASE_PWMS,
    five_phase_drive,
    five_phase_motor,
)
from pmsmjax.presets.six_phase import SIX_PHASE_CONTROLS, SIX_PHASE_PWMS, six_phase_drive, six_phase_motor
from pmsmjax.presets.three_phase import book_drive, book_scenario, pr_drive
from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.units import rad_s_to_rpm

SIX_UNBALANCE = (1.0, 1.0, 1.0, 1.5, 1.5, 1.5)  # set UVW's resistance 1.5 times set ABC's
FIVE_UNBALANCE = (1.0, 1.3, 0.8, 1.1, 1.2)  # phase resistance factors
THIRD = 0.05  # psi_f3 / psi_f of the five-phase third-harmonic cases
TORQUE_CONSTANT = 1.5 * 4 * 0.1827  # the book motor's, N m/A (docs/book_reference.md, reference motor)
TAIL = 500  # the last 50 ms of the book scenario: 10 N m at 1000 r/min


@dataclasses.dataclass(frozen=True)
class Phases:
    """What differs between the phase counts: the `layout` (its second plane, z1-z2 or x-y, is
    components 2:4 of the VSD), the control `schemes`, the modulators `pwms` and the
    `drive(motor=None, **options)` preset;
    `gradient_drive()` and `batch_drives()` build the drives of the gradient and batch checks (with the
    second plane excited: a resistance unbalance or a third-harmonic back-EMF)."""

    name: str
    layout: PhaseLayout
    schemes: tuple[str, ...]
    pwms: tuple[str, ...]
    drive: Callable
    gradient_drive: Callable
    batch_drives: Callable

    def __str__(self):
        return self.name


def _six_batch():
    base = six_phase_drive(control="double-dq", pwm="decoupled", resistance_scale=SIX_UNBALANCE)
    return [
        eqx.tree_at(
            lambda d: (d.controller.current.kc_d, d.machine.motor.R),
            base,
            (base.controller.current.kc_d * f, base.machine.motor.R * r),
        )
        for f, r in ((1.0, 1.0), (0.5, 1.2), (1.5, 0.8))
    ]


def _five_batch():
    base = five_phase_drive(five_phase_motor(third_harmonic=THIRD), pwm="carrier")
    return [
        eqx.tree_at(
            lambda d: (d.controller.current.z.kp, d.machine.motor.R, d.machine.motor.psi_f3),
            base,
            (base.controller.current.z.kp * f, base.machine.motor.R * r, base.machine.motor.psi_f3 * t),
        )
        for f, r, t in ((1.0, 1.0, 1.0), (0.5, 1.2, 0.5), (1.5, 0.8, 2.0))
    ]


SIX = Phases(
    "six-phase",
    SIX_PHASE,
    tuple(SIX_PHASE_CONTROLS),
    tuple(SIX_PHASE_PWMS),
    six_phase_drive,
    lambda: six_phase_drive(control="vsd", pwm="double-zs", resistance_scale=SIX_UNBALANCE, n_substeps=2),
    _six_batch,
)
FIVE = Phases(
    "five-phase",
    FIVE_PHASE,
    tuple(FIVE_PHASE_CONTROLS),
    tuple(FIVE_PHASE_PWMS),
    five_phase_drive,
    lambda: five_phase_drive(
        five_phase_motor(third_harmonic=THIRD), control="vsd", pwm="carrier", n_substeps=2
    ),
    _five_batch,
)
PHASES = (SIX, FIVE)


def second_plane_magnitude(trace, layout: PhaseLayout) -> np.ndarray:
    """``(N,)`` magnitude of the z1-z2 (six phases) or x-y (five phases) current, A."""
    i = np.asarray(vsd(trace.i_abc, layout))[:, 2:4]
    return np.hypot(i[:, 0], i[:, 1])


# The book-scenario runs, each simulated once for every test of the module: name -> drive builder.
RUNS = {
    "three-phase": book_drive,
    "three-phase-pr": pr_drive,
    **{f"six-phase-{s}": lambda s=s: six_phase_drive(control=s) for s in SIX.schemes},
    **{
        f"six-phase-{s}-unbalanced": lambda s=s: six_phase_drive(
            control=s, pwm="double-zs", resistance_scale=SIX_UNBALANCE
        )
        for s in SIX.schemes
    },
    **{f"five-phase-{s}": lambda s=s: five_phase_drive(control=s) for s in FIVE.schemes},
    **{
        f"five-phase-{s}-third": lambda s=s: five_phase_drive(
            five_phase_motor(third_harmonic=THIRD), control=s, pwm="carrier"
        )
        for s in FIVE.schemes
    },
    **{
        f"five-phase-{s}-unbalanced": lambda s=s: five_phase_drive(
            control=s, pwm="carrier", resistance_scale=FIVE_UNBALANCE
        )
        for s in FIVE.schemes
    },
}


@pytest.fixture(scope="module")
def book_run():
    """``name -> trace`` of :data:`RUNS` on the book scenario, simulated when first asked for."""
    cache = {}

    def get(name: str):
        if name not in cache:
            cache[name] = simulate(RUNS[name](), book_scenario())
        return cache[name]

    return get


@pytest.mark.slow
@pytest.mark.parametrize("ph, scheme", [(ph, s) for ph in PHASES for s in ph.schemes], ids=str)
def test_each_scheme_runs_the_book_scenario(book_run, ph, scheme):
    trace = book_run(f"{ph.name}-{scheme}")
    m = speed_step_summary(trace, load_time_s=0.2, current_limit_a=15.0)
    assert abs(m["final_speed_rpm"] - 1000.0) < 1.0
    assert abs(float(rad_s_to_rpm(trace.omega_m[1999])) - 1000.0) < 1.0  # settled before the load step
    assert 150.0 < m["speed_dip_rpm"] < 350.0 and m["recovery_time_s"] < 0.15
    assert m["current_limit_respected"] and m["overshoot_pct"] < 1.0
    # Balanced sinusoidal machine, modulators that null the second plane: no z1-z2 / x-y current.
    assert np.max(second_plane_magnitude(trace, ph.layout)) < 1e-9
    # The rewound machine has the book motor's torque constant and the same loop designs: the three-phase
    # book drive's speed response (PR: the three-phase PR drive), to within 1 % of 1000 r/min.
    three = book_run("three-phase-pr" if scheme == "pr" else "three-phase")
    assert np.max(np.abs(rad_s_to_rpm(trace.omega_m - three.omega_m))) < 10.0
    # 10 N m at 1000 r/min: i_q = (T_L + B w) / K_t = 9.20 A, i_d = 0.
    i_dq = np.asarray(trace.i_dq)[-TAIL:].mean(0)
    i_q = (10.0 + 0.008 * 1000 * np.pi / 30) / TORQUE_CONSTANT
    assert abs(i_dq[0]) < 0.05 and abs(i_dq[1] - i_q) < 0.05


@pytest.mark.slow
@pytest.mark.parametrize("scheme", SIX.schemes)
def test_z_loops_remove_the_z_current_of_a_resistance_unbalance(book_run, scheme):
    z = second_plane_magnitude(book_run(f"six-phase-{scheme}-unbalanced"), SIX_PHASE)[-TAIL:]
    if scheme == "conventional":
        # z open loop: the unbalance voltage (R_UVW - R_ABC)/2 i_ab drives (R + j w L_ls)^-1 of it.
        assert np.min(z) > 1.5
    else:
        conventional = second_plane_magnitude(book_run("six-phase-conventional-unbalanced"), SIX_PHASE)
        assert np.max(z) < 0.01, scheme
        assert np.max(z) < 0.01 * np.min(conventional[-TAIL:])


@pytest.mark.slow
def test_double_dq_and_vsd_designed_equivalently_give_the_same_response(book_run):
    for variant in ("", "-unbalanced"):
        v, d = book_run(f"six-phase-vsd{variant}"), book_run(f"six-phase-double-dq{variant}")
        assert np.max(np.abs(d.omega_m - v.omega_m)) < 0.01 * np.max(np.abs(v.omega_m))
        assert np.max(np.abs(d.i_abc - v.i_abc)) < 0.01 * np.max(np.abs(v.i_abc))
    # Without the cross-coupling compensation the double-dq loops are another controller: its common-mode
    # gain is the set's self gain a_c (L_d + L_ls)/2, about half the VSD loop's a_c L_d.
    plain = eqx.tree_at(
        lambda d: d.controller.current,
        six_phase_drive(control="double-dq"),
        double_dq_design(six_phase_motor(), 1100.0, cross_coupling=False),
    )
    p = simulate(plain, book_scenario())
    vsd_i_dq = book_run("six-phase-vsd").i_dq
    assert np.max(np.abs(p.i_dq - vsd_i_dq)) > 0.1 * np.max(np.abs(vsd_i_dq))


@pytest.mark.slow
def test_xy_loops_remove_the_current_of_a_third_harmonic_back_emf(book_run):
    motor = five_phase_motor(third_harmonic=THIRD)
    w_e = 4 * 1000 * np.pi / 30
    # x-y open loop (voltage 0): |i_xy| = 3 w_e psi_f3 / |R + j 3 w_e L_ls| in steady state.
    emf = 3 * w_e * float(motor.psi_f3)
    expected = emf / abs(float(motor.R) + 3j * w_e * float(motor.L_ls))
    open_loop = second_plane_magnitude(book_run("five-phase-conventional-third"), FIVE_PHASE)[-TAIL:]
    np.testing.assert_allclose(open_loop, expected, rtol=0.01)
    closed = second_plane_magnitude(book_run("five-phase-vsd-third"), FIVE_PHASE)[-TAIL:]
    assert np.max(closed) < 0.01 and np.max(closed) < 1e-3 * expected
    m = speed_step_summary(book_run("five-phase-vsd-third"), load_time_s=0.2, current_limit_a=15.0)
    assert abs(m["final_speed_rpm"] - 1000.0) < 1.0


@pytest.mark.slow
def test_xy_pr_removes_the_xy_current_of_a_resistance_unbalance(book_run):
    runs = {name: book_run(f"five-phase-{name}-unbalanced") for name in FIVE.schemes}
    tail = {name: second_plane_magnitude(trace, FIVE_PHASE)[-TAIL:] for name, trace in runs.items()}
    assert np.min(tail["conventional"]) > 0.3  # the unbalance drives x-y current at +-w_e
    assert np.max(tail["pr"]) < 0.01 and np.max(tail["pr"]) < 0.01 * np.max(tail["conventional"])
    # The 3 theta_e x-y PI sees it as a ripple at 2 w_e and 4 w_e, not a constant: it removes little.
    assert np.max(tail["vsd"]) > 0.5 * np.max(tail["conventional"])
    for trace in runs.values():
        m = speed_step_summary(trace, load_time_s=0.2, current_limit_a=15.0)
        assert abs(m["final_speed_rpm"] - 1000.0) < 1.0


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


@pytest.mark.slow
@pytest.mark.parametrize("ph", PHASES, ids=str)
def test_gradient_through_the_loop_matches_central_differences(ph):
    """Speed error and second-plane current (excited by the unbalance or the third harmonic) against the
    speed, q-axis and second-plane gains."""
    drive = ph.gradient_drive()
    scenario = short_scenario()

    @jax.jit
    def loss(x):
        tr = simulate(with_gains(drive, x), scenario)
        i_rest = vsd(tr.i_abc, ph.layout)[:, 2:4]
        return jnp.mean((tr.speed_ref - tr.omega_m) ** 2) * 1e-2 + jnp.mean(i_rest**2) * 1e2

    x0 = jnp.zeros(4)
    g = np.asarray(jax.grad(loss)(x0))
    h = 1e-5
    fd = np.array([(loss(x0.at[k].add(h)) - loss(x0.at[k].add(-h))) / (2 * h) for k in range(4)])
    assert np.all(np.abs(g) > 1e-8)  # every gain moves the loss
    np.testing.assert_allclose(g, fd, rtol=1e-4)


@pytest.mark.slow
@pytest.mark.parametrize("ph", PHASES, ids=str)
def test_vmap_batch_equals_single_runs(ph):
    drives = ph.batch_drives()
    scenario = short_scenario()
    batch = jax.tree.map(lambda *xs: jnp.stack(xs), *drives)
    batched = jax.vmap(lambda d: simulate(d, scenario))(batch)
    for k, d in enumerate(drives):
        single = simulate(d, scenario)
        np.testing.assert_allclose(batched.i_abc[k], single.i_abc, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(batched.omega_m[k], single.omega_m, rtol=1e-12, atol=1e-10)


@pytest.mark.parametrize("ph, other", [(SIX, FIVE), (FIVE, SIX)], ids=str)
def test_drive_and_controller_checks(ph, other):
    """The controller refuses a motor model of another phase count; the drive refuses a modulator or a
    bridge of another leg count; the presets name their choices."""
    three, drive, other_drive = book_drive(), ph.drive(), other.drive()
    n = ph.layout.n
    for model in (three.controller.model, other_drive.controller.model):
        with pytest.raises(ParameterError, match=f"{ph.name} motor"):
            MultiPhaseFOC(
                model=model,
                speed=drive.controller.speed,
                current=drive.controller.current,
                current_limit=15.0,
            )
    with pytest.raises(ParameterError, match=f"modulator drives {n} legs"):
        Drive(three.machine, three.controller, drive.modulator, three.bridge)
    with pytest.raises(ParameterError, match=f"modulator drives {n} legs"):
        Drive(other_drive.machine, other_drive.controller, drive.modulator, other_drive.bridge)
    with pytest.raises(ParameterError, match="bridge has 3 legs"):
        Drive(drive.machine, drive.controller, drive.modulator, three.bridge)
    with pytest.raises(ParameterError, match=f"{ph.name} control must be one of"):
        ph.drive(control="dtc")
    with pytest.raises(ParameterError, match=f"{ph.name} pwm must be one of"):
        ph.drive(pwm="svpwm")
    # Each machine's own schemes and modulators are refused by the other's preset.
    for scheme in sorted(set(ph.schemes) - set(other.schemes)):
        with pytest.raises(ParameterError, match=f"{other.name} control must be one of"):
            other.drive(control=scheme)
    for pwm in ph.pwms:
        with pytest.raises(ParameterError, match=f"{other.name} pwm must be one of"):
            other.drive(pwm=pwm)
