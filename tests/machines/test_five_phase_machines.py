"""The five-phase PMSM in its three frames (natural 5x5, stationary VSD alpha-beta/x-y, dq + x-y) against an
independent scipy reference, and the physics of the 5x5 Clarke decomposition (BOOK.md chapter 10).

Must-show: under open-loop, piecewise-constant phase-voltage sequences (given as their alpha-beta/x-y
components: dq steering plus random alpha-beta and x-y parts, 250 periods of 1e-4 s), with the speed
imposed and as a state, for the surface and the salient five-phase motor, once with unbalanced phase
resistances and once with a third-harmonic back-EMF, every frame model integrated by
``pmsmjax.machines.advance`` (10 RK4 sub-steps per period) stays within 0.1 % of the peak phase current of a
scipy ``solve_ivp`` (DOP853, rtol 1e-10, atol 1e-12) solution of the natural-frame equations written here
(5x5 inductance, the isolated star by its neutral voltage, torque from the co-energy derivative written
out). The x-y subspace sees only the leakage inductance and, without a third harmonic, makes no torque;
every model conserves energy; the dq torque is ``2.5 p_n [psi_f i_q + (L_d - L_q) i_d i_q]``.
"""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from pmsmjax import ParameterError
from pmsmjax.frames.multiphase import FIVE_PHASE, SIX_PHASE, inverse_vsd, vsd
from pmsmjax.machines import MachineInput, advance
from pmsmjax.machines.pmsm_multiphase import MultiPhasePMSMdq, MultiPhasePMSMNatural, MultiPhasePMSMVSD
from pmsmjax.presets.five_phase import (
    FIVE_PHASE_MOTOR_FILE,
    five_phase_machine,
    five_phase_motor,
    load_five_phase_motor,
)
from pmsmjax.presets.six_phase import six_phase_motor

TS = 1e-4
N = 250
SPEED = 1000.0 * 2 * math.pi / 60
THETA0 = 0.3
I_VSD0 = (1.0, -0.5, 0.3, 0.2)
FRAMES = ("natural", "vsd", "dq")
G = 2 * np.pi * np.arange(5) / 5  # phase axes A..E, written out
# The 5x5 amplitude-invariant Clarke, written from its definition: rows alpha, beta, x, y, zero sequence.
T_TABLE = np.stack(
    [0.4 * np.cos(G), 0.4 * np.sin(G), 0.4 * np.cos(3 * G), 0.4 * np.sin(3 * G), 0.2 * np.ones(5)]
)
T_INV = np.linalg.inv(T_TABLE)


def numbers(salient: bool, third: float = 0.0) -> dict:
    # Written out from the derivation in pmsmjax/presets/five_phase.py (book motor, 3/5 of the turns per phase).
    L_ls3, k = 0.525e-3, 0.6
    Lls = k * k * L_ls3
    return dict(
        R=k * 0.958,
        Ld=Lls + k * (5.25e-3 - L_ls3),
        Lq=Lls + k * ((12e-3 if salient else 5.25e-3) - L_ls3),
        Lls=Lls,
        psi=k * 0.1827,
        psi3=third * k * 0.1827,
        J=0.003,
        B=0.008,
        p=4,
    )


# --- the independent reference: natural-frame equations in NumPy, scipy solve_ivp ------------------
def natural_inductance(P, th):
    L0 = (P["Ld"] + P["Lq"] - 2 * P["Lls"]) / 5
    L2 = (P["Ld"] - P["Lq"]) / 5
    gx, gy = G[:, None], G[None, :]
    L = P["Lls"] * np.eye(5) + L0 * np.cos(gx - gy) + L2 * np.cos(2 * th - gx - gy)
    dL = -2 * L2 * np.sin(2 * th - gx - gy)
    return L, dL


def pm_flux_derivative(P, th):
    """d psi_PM / d theta_e, (5,) Wb/rad, with the optional third harmonic."""
    return -P["psi"] * np.sin(th - G) - 3 * P["psi3"] * np.sin(3 * (th - G))


def reference_torque(P, i, th):
    _, dL = natural_inductance(P, th)
    return P["p"] * (0.5 * i @ dL @ i + i @ pm_flux_derivative(P, th))


def natural_rhs(t, x, u_vsd, load, P, r_scale, imposed):
    i, w_m, th = x[:5], x[5], x[6]
    L, dL = natural_inductance(P, th)
    w_e = P["p"] * w_m
    rhs = T_INV[:, :4] @ u_vsd - P["R"] * r_scale * i - w_e * (dL @ i + pm_flux_derivative(P, th))
    # Isolated star: the neutral voltage keeps the current sum constant (KKT system).
    K = np.block([[L, np.ones((5, 1))], [np.ones((1, 5)), np.zeros((1, 1))]])
    di = np.linalg.solve(K, np.concatenate([rhs, [0.0]]))[:5]
    dw = 0.0 if imposed else (reference_torque(P, i, th) - load - P["B"] * w_m) / P["J"]
    return np.concatenate([di, [dw, w_e]])


def reference(P, x0, u, load, r_scale, imposed):
    out = np.empty((len(u) + 1, 7))
    out[0] = x = np.asarray(x0, float)
    for k in range(len(u)):
        sol = solve_ivp(
            natural_rhs,
            (0.0, TS),
            x,
            method="DOP853",
            rtol=1e-10,
            atol=1e-12,
            args=(u[k], load[k], P, r_scale, imposed),
        )
        assert sol.success
        out[k + 1] = x = sol.y[:, -1]
    return out


def voltage_sequence(P, imposed, seed):
    """``(N, 4)`` [alpha, beta, x, y] voltages of the phase-voltage sequence: a rotating component steering
    (i_d, i_q) along a plan (cancelling most of the back-EMF at the imposed 1000 r/min; accelerating the
    rotor otherwise), plus uniform random +-8 V alpha-beta and +-3 V x-y components."""
    rng = np.random.default_rng(seed)
    load = np.zeros(N) if imposed else np.where(np.arange(N) < N // 2, 0.3, 1.0)
    i_d, i_q = (-1.0, 4.0) if imposed else (0.0, 6.0)
    w, th = (SPEED, THETA0) if imposed else (0.0, THETA0)
    kt = 2.5 * P["p"] * P["psi"]
    u = np.empty((N, 4))
    for k in range(N):
        w_e = P["p"] * w
        u_d = P["R"] * i_d - w_e * P["Lq"] * i_q
        u_q = P["R"] * i_q + w_e * (P["Ld"] * i_d + P["psi"])
        a = th + 0.5 * TS * w_e
        u[k, :2] = [u_d * np.cos(a) - u_q * np.sin(a), u_d * np.sin(a) + u_q * np.cos(a)]
        u[k, :2] += rng.uniform(-8, 8, 2)
        u[k, 2:] = rng.uniform(-3, 3, 2)
        if not imposed:
            w += TS * (kt * i_q - load[k] - P["B"] * w) / P["J"]
        th += TS * P["p"] * w
    return u, load


@eqx.filter_jit
def simulate_model(machine, x0_state, u, load, n_substeps):
    """Per-period phase currents, speed and torque of ``machine`` under the held VSD voltages ``u``."""

    def body(s, inp):
        uk, lk = inp
        s = advance(machine, s, MachineInput(uk, lk, "stator"), TS, n_substeps)
        return s, (machine.phase_currents(s), s.omega_m, machine.electromagnetic_torque(s))

    return jax.lax.scan(body, x0_state, (u, load))[1]


# (salient, imposed speed, resistance factors, third-harmonic fraction)
CASES = [
    (False, True, None, 0.0),
    (False, False, None, 0.0),
    (True, False, None, 0.0),
    (True, True, (1.0, 1.3, 0.8, 1.1, 1.2), 0.0),
    (True, False, None, 0.1),
]


@pytest.fixture(
    scope="module",
    params=CASES,
    ids=lambda c: (
        f"{'salient' if c[0] else 'surface'}-{'imposed' if c[1] else 'dynamic'}"
        f"{'-unbalanced' if c[2] else ''}{'-third-harmonic' if c[3] else ''}"
    ),
)
def case(request):
    salient, imposed, r_scale, third = request.param
    P = numbers(salient, third)
    u, load = voltage_sequence(P, imposed, seed=5 + salient + 2 * imposed)
    w0 = SPEED if imposed else 0.0
    scale = np.ones(5) if r_scale is None else np.asarray(r_scale)
    x0 = np.concatenate([T_INV[:, :4] @ np.asarray(I_VSD0), [w0, THETA0]])
    ref = reference(P, x0, u, load, scale, imposed)
    motor = five_phase_motor(salient, third_harmonic=third or None)
    runs = {}
    for frame in FRAMES:
        m = five_phase_machine(motor, frame, "imposed" if imposed else "dynamic", r_scale)
        s0 = m.initial_state_vsd(I_VSD0, w0, THETA0)
        out = simulate_model(m, s0, jnp.asarray(u), jnp.asarray(load), 10)
        runs[frame] = [np.asarray(a) for a in out]
    return P, ref, runs


def test_every_frame_matches_the_natural_frame_reference(case):
    P, ref, runs = case
    i_ref = ref[1:, :5]
    peak = np.max(np.abs(i_ref))
    assert peak > 5.0  # the sequence excites several amperes
    for name, (i_ph, w, _) in runs.items():
        err = np.max(np.abs(i_ph - i_ref)) / peak
        assert err < 1e-3, (name, err)
        assert np.max(np.abs(w - ref[1:, 5])) < 1e-3 * max(np.max(np.abs(ref[:, 5])), 1.0), name
    if np.ptp(ref[:, 5]) > 0:  # the speed really moves when it is a state
        assert np.ptp(ref[:, 5]) > 20.0


def test_torque_matches_the_reference_coenergy_torque(case):
    P, ref, runs = case
    torque = np.array([reference_torque(P, x[:5], x[6]) for x in ref[1:]])
    scale = np.max(np.abs(torque))
    for name, (_, _, T_e) in runs.items():
        assert np.max(np.abs(T_e - torque)) < 1e-3 * scale, name


def test_clarke_matrix_and_the_dq_torque_formula():
    np.testing.assert_allclose(np.asarray(vsd(jnp.eye(5), FIVE_PHASE)).T, T_TABLE, atol=1e-15)
    np.testing.assert_allclose(np.asarray(inverse_vsd(jnp.eye(5), FIVE_PHASE)).T, T_INV, atol=1e-14)
    # A balanced set X cos(th - g_k) has |alpha + j beta| = X and x = y = 0; its third harmonic lies in x-y.
    th = 0.7
    ab = np.asarray(vsd(3.0 * np.cos(th - G), FIVE_PHASE))
    np.testing.assert_allclose(ab, [3 * np.cos(th), 3 * np.sin(th), 0, 0, 0], atol=1e-14)
    xy = np.asarray(vsd(np.cos(3 * (th - G)), FIVE_PHASE))
    np.testing.assert_allclose(xy, [0, 0, np.cos(3 * th), np.sin(3 * th), 0], atol=1e-14)
    # T_e = 2.5 p_n [psi_f i_q + (L_d - L_q) i_d i_q] (book ch. 10) against the co-energy torque.
    P = numbers(True)
    motor = five_phase_motor(True)
    for i_d, i_q in ((0.0, 9.0), (-3.0, 6.0), (2.0, -4.0)):
        i_ph = T_INV[:, :2] @ np.array(
            [i_d * np.cos(th) - i_q * np.sin(th), i_d * np.sin(th) + i_q * np.cos(th)]
        )
        expected = 2.5 * 4 * (P["psi"] * i_q + (P["Ld"] - P["Lq"]) * i_d * i_q)
        np.testing.assert_allclose(reference_torque(P, i_ph, th), expected, rtol=1e-12)
        for frame in FRAMES:
            m = five_phase_machine(motor, frame)
            s = m.initial_state_vsd(np.asarray(T_TABLE[:4] @ i_ph), 0.0, th)
            np.testing.assert_allclose(float(m.electromagnetic_torque(s)), expected, rtol=1e-12)


@pytest.mark.parametrize("salient", [False, True])
def test_xy_subspace_sees_only_leakage_and_makes_no_torque(salient):
    motor = five_phase_motor(salient)
    nat = MultiPhasePMSMNatural(motor, layout=FIVE_PHASE)
    Ls = float(motor.L_ls)
    for th in np.linspace(-3, 3, 7):
        L_vsd = T_TABLE @ np.asarray(nat.inductance(th)) @ T_INV
        np.testing.assert_allclose(L_vsd[2:, 2:], Ls * np.eye(3), atol=1e-15)  # x-y and zero: L_ls
        np.testing.assert_allclose(L_vsd[:2, 2:], 0.0, atol=1e-15)
        np.testing.assert_allclose(L_vsd[2:, :2], 0.0, atol=1e-15)
    rng = np.random.default_rng(0)
    for frame in FRAMES:
        m = five_phase_machine(motor, frame)
        for _ in range(5):
            i = rng.normal(size=4) * 5
            th = rng.uniform(-np.pi, np.pi)
            with_xy = m.electromagnetic_torque(m.initial_state_vsd(i, 10.0, th))
            without = m.electromagnetic_torque(m.initial_state_vsd(np.r_[i[:2], 0.0, 0.0], 10.0, th))
            assert abs(float(with_xy - without)) < 1e-12 * max(1.0, abs(float(without)))


def test_third_harmonic_makes_xy_torque():
    """With psi_f3, an x-y current aligned with j e^{j 3th} makes ``2.5 p_n 3 psi_f3 |i_xy|``."""
    P = numbers(False, 0.1)
    motor = five_phase_motor(third_harmonic=0.1)
    th, amp = 0.4, 2.0
    i_xy = amp * np.array([-np.sin(3 * th), np.cos(3 * th)])
    expected = 2.5 * 4 * 3 * P["psi3"] * amp
    np.testing.assert_allclose(reference_torque(P, T_INV[:, 2:4] @ i_xy, th), expected, rtol=1e-12)
    for frame in FRAMES:
        m = five_phase_machine(motor, frame)
        s = m.initial_state_vsd(np.r_[0.0, 0.0, i_xy], 0.0, th)
        np.testing.assert_allclose(float(m.electromagnetic_torque(s)), expected, rtol=1e-12)
    assert five_phase_machine(motor, "dq").split_advance is None  # the angle drives x-y: no split


@pytest.mark.parametrize("third", [0.0, 0.1])
def test_power_balance(third):
    """Electrical power in = copper loss + rate of magnetic energy + mechanical power, at random states, for
    every model (energy from the natural inductance written in this test)."""
    P = numbers(True, third)
    motor = five_phase_motor(True, third_harmonic=third or None)
    rng = np.random.default_rng(1)
    for frame in FRAMES:
        m = five_phase_machine(motor, frame)
        for _ in range(4):
            state = m.initial_state_vsd(rng.normal(size=4) * 4, rng.uniform(-150, 150), rng.uniform(-3, 3))
            u = MachineInput(jnp.asarray(rng.normal(size=4) * 60), jnp.asarray(0.0))
            dx = m.vector_field(None, state, u)
            i_ph, di_ph = jax.jvp(m.phase_currents, (state,), (dx,))
            i_ph, di_ph = np.asarray(i_ph), np.asarray(di_ph)
            th = float(state.theta_e)
            L, dL = natural_inductance(P, th)
            w_e = P["p"] * float(state.omega_m)
            # d/dt of the stored magnetic energy 1/2 i L i; the magnet's flux enters as the back-EMF power.
            dW = i_ph @ L @ di_ph + 0.5 * w_e * i_ph @ dL @ i_ph
            p_emf = w_e * float(i_ph @ pm_flux_derivative(P, th))
            p_in = float(np.asarray(T_INV[:, :4] @ np.asarray(u.u)) @ i_ph)
            p_cu = P["R"] * float(i_ph @ i_ph)
            p_mech = float(m.electromagnetic_torque(state)) * float(state.omega_m)
            scale = abs(p_in) + p_cu + abs(p_mech)
            assert abs(p_in - (p_cu + dW + p_mech)) < 1e-9 * scale, frame
            # The mechanical power is the air-gap power: reluctance plus magnet back-EMF.
            assert abs(p_mech - (0.5 * w_e * i_ph @ dL @ i_ph + p_emf)) < 1e-9 * scale, frame


def test_preset_file_and_checks():
    from_file, preset = load_five_phase_motor(FIVE_PHASE_MOTOR_FILE), five_phase_motor()
    for f in ("R", "L_d", "L_q", "psi_f", "L_ls", "J", "B"):
        np.testing.assert_allclose(float(getattr(from_file, f)), float(getattr(preset, f)), rtol=1e-12)
    assert from_file.n_phases == 5 and from_file.psi_f3 is None
    # The torque constant is the book motor's: 1.5 * 4 * 0.1827.
    np.testing.assert_allclose(float(preset.torque_constant), 1.5 * 4 * 0.1827, rtol=1e-12)
    with pytest.raises(ParameterError, match="order-3 plane"):
        MultiPhasePMSMdq(six_phase_motor().__class__(**{**_fields(six_phase_motor()), "psi_f3": 0.01}))
    with pytest.raises(ParameterError, match="n_phases = 5"):
        MultiPhasePMSMVSD(five_phase_motor(), layout=SIX_PHASE)


def _fields(m):
    return {
        f: getattr(m, f) for f in ("R", "L_d", "L_q", "psi_f", "L_ls", "J", "B", "pole_pairs", "n_phases")
    }
