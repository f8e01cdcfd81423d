"""The dual three-phase PMSM in its four frames (natural 6x6, stationary VSD, dq + z1-z2, double dq)
against an independent scipy reference, and the physics the VSD claims (BOOK.md chapter 7).

Must-show: under open-loop, piecewise-constant VSD voltage sequences (alpha-beta steering plus random
z1-z2 and alpha-beta components, 250 periods of 1e-4 s), with the speed imposed and as a state, for the
surface and the salient six-phase motor (and once with unbalanced phase resistances), every frame model
integrated by ``pmsmjax.machines.advance`` with 10 RK4 sub-steps per period stays within 0.1 % of the peak
phase current of a scipy ``solve_ivp`` (DOP853, rtol 1e-10, atol 1e-12) solution of the natural-frame
equations written here (6x6 inductance matrix, isolated stars by their neutral voltages, torque from the
co-energy derivative written out). The z1-z2 subspace sees only the leakage inductance and makes no torque;
every model conserves energy.
"""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from pmsmjax import ParameterError
from pmsmjax.frames.multiphase import PhaseLayout
from pmsmjax.machines import MachineInput, MachineState, advance
from pmsmjax.machines.multiphase_motor import MultiPhaseParameters
from pmsmjax.machines.pmsm6 import PMSM6DoubleDQ
from pmsmjax.machines.pmsm_multiphase import MultiPhasePMSMdq, MultiPhasePMSMNatural, MultiPhasePMSMVSD
from pmsmjax.presets.six_phase import six_phase_motor

TS = 1e-4
N = 250
SPEED = 1000.0 * 2 * math.pi / 60
THETA0 = 0.3
I_VSD0 = (1.0, -0.5, 0.3, 0.2)
MODELS = (MultiPhasePMSMNatural, MultiPhasePMSMVSD, MultiPhasePMSMdq, PMSM6DoubleDQ)
G = np.array([0.0, 2 * np.pi / 3, 4 * np.pi / 3, np.pi / 6, 5 * np.pi / 6, 3 * np.pi / 2])  # written out
S3 = math.sqrt(3.0)
# Zhao & Lipo's amplitude-invariant VSD table (A, B, C, U, V, W), rows alpha, beta, z1, z2, o1, o2.
T_TABLE = (1.0 / 3.0) * np.array(
    [
        [1, -0.5, -0.5, S3 / 2, -S3 / 2, 0],
        [0, S3 / 2, -S3 / 2, 0.5, 0.5, -1],
        [1, -0.5, -0.5, -S3 / 2, S3 / 2, 0],
        [0, -S3 / 2, S3 / 2, 0.5, 0.5, -1],
        [1, 1, 1, 0, 0, 0],
        [0, 0, 0, 1, 1, 1],
    ]
)
T_INV = np.linalg.inv(T_TABLE)


def numbers(salient: bool) -> dict:
    # Written out from the derivation in pmsmjax/presets/six_phase.py (book motor, same-copper rewind).
    L_ls3 = 0.525e-3
    return dict(
        R=0.479,
        Ld=5.25e-3 / 2 - L_ls3 / 4,
        Lq=(12e-3 if salient else 5.25e-3) / 2 - L_ls3 / 4,
        Lls=L_ls3 / 4,
        psi=0.1827 / 2,
        J=0.003,
        B=0.008,
        p=4,
    )


# --- the independent reference: natural-frame equations in NumPy, scipy solve_ivp ------------------
def natural_inductance(P, th):
    L0 = (P["Ld"] + P["Lq"] - 2 * P["Lls"]) / 6
    L2 = (P["Ld"] - P["Lq"]) / 6
    gx, gy = G[:, None], G[None, :]
    L = P["Lls"] * np.eye(6) + L0 * np.cos(gx - gy) + L2 * np.cos(2 * th - gx - gy)
    dL = -2 * L2 * np.sin(2 * th - gx - gy)
    return L, dL


def natural_rhs(t, x, u_vsd, load, P, r_scale, imposed):
    i, w_m, th = x[:6], x[6], x[7]
    L, dL = natural_inductance(P, th)
    dpm = -P["psi"] * np.sin(th - G)
    w_e = P["p"] * w_m
    rhs = T_INV[:, :4] @ u_vsd - P["R"] * r_scale * i - w_e * (dL @ i + dpm)
    # Isolated stars: the neutral voltages v keep each star's current sum constant (KKT system).
    Gs = np.zeros((6, 2))
    Gs[:3, 0] = Gs[3:, 1] = 1.0
    K = np.block([[L, Gs], [Gs.T, np.zeros((2, 2))]])
    di = np.linalg.solve(K, np.concatenate([rhs, np.zeros(2)]))[:6]
    T_e = P["p"] * (0.5 * i @ dL @ i + i @ dpm)
    dw = 0.0 if imposed else (T_e - load - P["B"] * w_m) / P["J"]
    return np.concatenate([di, [dw, w_e]])


def reference(P, x0, u, load, r_scale, imposed):
    out = np.empty((len(u) + 1, 8))
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
    """``(N, 4)`` VSD voltages: a rotating component steering (i_d, i_q) along a plan (cancelling most of
    the back-EMF at the imposed 1000 r/min; accelerating the rotor otherwise), plus uniform random
    +-8 V alpha-beta and +-3 V z1-z2 components (z1-z2 currents of several amperes)."""
    rng = np.random.default_rng(seed)
    load = np.zeros(N) if imposed else np.where(np.arange(N) < N // 2, 0.3, 1.0)
    i_d, i_q = (-1.0, 4.0) if imposed else (0.0, 6.0)
    w, th = (SPEED, THETA0) if imposed else (0.0, THETA0)
    kt = 3 * P["p"] * P["psi"]
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


def initial_phase_currents():
    return T_INV[:, :4] @ np.asarray(I_VSD0)


@eqx.filter_jit
def simulate_model(machine, x0_state, u, load, n_substeps):
    """Per-period phase currents, speed and torque of ``machine`` under the held VSD voltages ``u``."""

    def body(s, inp):
        uk, lk = inp
        s = advance(machine, s, MachineInput(uk, lk, "stator"), TS, n_substeps)
        return s, (machine.phase_currents(s), s.omega_m, machine.electromagnetic_torque(s))

    return jax.lax.scan(body, x0_state, (u, load))[1]


@eqx.filter_jit
def advance_jit(machine, state, u, duration, n_substeps):
    return advance(machine, state, MachineInput(u, jnp.zeros(()), "stator"), duration, n_substeps)


CASES = [(False, True, None), (False, False, None), (True, True, None), (True, False, None)]
CASES.append((False, True, (1.0, 1.0, 1.0, 1.3, 1.3, 1.3)))
CASES.append((True, False, (1.0, 1.2, 0.9, 1.1, 1.0, 1.3)))


@pytest.fixture(
    scope="module",
    params=CASES,
    ids=lambda c: (
        f"{'salient' if c[0] else 'surface'}-"
        f"{'imposed' if c[1] else 'dynamic'}{'-unbalanced' if c[2] else ''}"
    ),
)
def case(request):
    salient, imposed, r_scale = request.param
    P = numbers(salient)
    u, load = voltage_sequence(P, imposed, seed=3 + salient + 2 * imposed)
    w0 = SPEED if imposed else 0.0
    scale = np.ones(6) if r_scale is None else np.asarray(r_scale)
    ref = reference(P, np.concatenate([initial_phase_currents(), [w0, THETA0]]), u, load, scale, imposed)
    motor = six_phase_motor(salient)
    runs = {}
    for cls in MODELS:
        m = cls(motor, mechanics="imposed" if imposed else "dynamic", resistance_scale=r_scale)
        s0 = m.initial_state_vsd(I_VSD0, w0, THETA0)
        out = simulate_model(m, s0, jnp.asarray(u), jnp.asarray(load), 10)
        runs[cls.__name__] = [np.asarray(a) for a in out]
    return P, ref, runs


def test_every_frame_matches_the_natural_frame_reference(case):
    P, ref, runs = case
    i_ref = ref[1:, :6]
    peak = np.max(np.abs(i_ref))
    assert peak > 5.0  # the sequence excites several amperes
    for name, (i_ph, w, _) in runs.items():
        err = np.max(np.abs(i_ph - i_ref)) / peak
        assert err < 1e-3, (name, err)
        assert np.max(np.abs(w - ref[1:, 6])) < 1e-3 * max(np.max(np.abs(ref[:, 6])), 1.0), name
    # The speed really moves when it is a state.
    if np.ptp(ref[:, 6]) > 0:
        assert np.ptp(ref[:, 6]) > 20.0


def test_torque_matches_the_reference_coenergy_torque(case):
    P, ref, runs = case
    torque = []
    for x in ref[1:]:
        _, dL = natural_inductance(P, x[7])
        i = x[:6]
        torque.append(P["p"] * (0.5 * i @ dL @ i + i @ (-P["psi"] * np.sin(x[7] - G))))
    torque = np.asarray(torque)
    scale = np.max(np.abs(torque))
    for name, (_, _, T_e) in runs.items():
        assert np.max(np.abs(T_e - torque)) < 1e-3 * scale, name


@pytest.mark.parametrize("salient", [False, True])
def test_z_subspace_sees_only_leakage_and_makes_no_torque(salient):
    motor = six_phase_motor(salient)
    nat = MultiPhasePMSMNatural(motor)
    Ls = float(motor.L_ls)
    for th in np.linspace(-3, 3, 7):
        L_vsd = T_TABLE @ np.asarray(nat.inductance(th)) @ T_INV
        np.testing.assert_allclose(L_vsd[2:, 2:], Ls * np.eye(4), atol=1e-15)  # z1-z2 and o1-o2: L_ls
        np.testing.assert_allclose(L_vsd[:2, 2:], 0.0, atol=1e-15)
        np.testing.assert_allclose(L_vsd[2:, :2], 0.0, atol=1e-15)
    # Torque does not depend on z1-z2 currents, in any model.
    rng = np.random.default_rng(0)
    for cls in MODELS:
        m = cls(motor)
        for _ in range(5):
            i = rng.normal(size=4) * 5
            th = rng.uniform(-np.pi, np.pi)
            with_z = m.electromagnetic_torque(m.initial_state_vsd(i, 10.0, th))
            without = m.electromagnetic_torque(m.initial_state_vsd(np.r_[i[:2], 0.0, 0.0], 10.0, th))
            assert abs(float(with_z - without)) < 1e-12 * max(1.0, abs(float(without)))
    # A z1-z2 voltage step from rest: i_z(t) = (u/R)(1 - exp(-t R/L_ls)), exactly first order.
    u_z, t = np.array([2.0, -1.0]), 3e-4
    expected = u_z / float(motor.R) * (1.0 - math.exp(-t * float(motor.R) / Ls))
    for cls in MODELS:
        m = cls(motor, mechanics="imposed")
        s = advance_jit(m, m.initial_state_vsd(np.zeros(4)), jnp.r_[0.0, 0.0, u_z], t, 60)
        np.testing.assert_allclose(m.vsd_currents(s), np.r_[0.0, 0.0, expected], atol=1e-9 * 4.0)


@pytest.mark.parametrize("salient", [False, True])
def test_power_balance(salient):
    """Electrical power in = copper loss + rate of magnetic energy + mechanical power, at random states,
    for every model (energy from the natural inductance written in this test)."""
    P = numbers(salient)
    motor = six_phase_motor(salient)
    rng = np.random.default_rng(1)
    for cls in MODELS:
        m = cls(motor)
        for _ in range(4):
            state = m.initial_state_vsd(rng.normal(size=4) * 4, rng.uniform(-150, 150), rng.uniform(-3, 3))
            u = MachineInput(jnp.asarray(rng.normal(size=4) * 60), jnp.asarray(0.0))
            dx = m.vector_field(None, state, u)
            i_ph, di_ph = jax.jvp(m.phase_currents, (state,), (dx,))
            i_ph, di_ph = np.asarray(i_ph), np.asarray(di_ph)
            th = float(state.theta_e)
            L, dL = natural_inductance(P, th)
            w_e = P["p"] * float(state.omega_m)
            dW = i_ph @ L @ di_ph + 0.5 * w_e * i_ph @ dL @ i_ph
            p_in = float(np.asarray(T_INV[:, :4] @ np.asarray(u.u)) @ i_ph)
            p_cu = P["R"] * float(i_ph @ i_ph)
            p_mech = float(m.electromagnetic_torque(state)) * float(state.omega_m)
            assert abs(p_in - (p_cu + dW + p_mech)) < 1e-9 * (abs(p_in) + p_cu + abs(p_mech)), cls.__name__


def test_isolated_stars_hold_zero_star_currents_under_unbalance():
    m = MultiPhasePMSMNatural(six_phase_motor(), resistance_scale=(1.0, 1.4, 0.8, 1.0, 1.3, 0.9))
    s = m.initial_state_vsd([2.0, 1.0, 0.5, -0.5], 80.0, 0.1)
    for _ in range(20):
        s = advance_jit(m, s, jnp.asarray([40.0, -30.0, 3.0, 2.0]), TS, 5)
    i = np.asarray(s.currents)
    assert abs(i[:3].sum()) < 1e-12 and abs(i[3:].sum()) < 1e-12


def test_linearisation_of_the_dq_model_shows_the_z_pole():
    """``linearise`` on the six-phase dq model: the z1-z2 rows are ``-R/L_ls`` on the diagonal, ``1/L_ls``
    from their voltages, and decoupled from everything else."""
    from pmsmjax.machines import linearise

    motor = six_phase_motor()
    m = MultiPhasePMSMdq(motor)
    A, B = linearise(
        m, m.initial_state_vsd([3.0, 1.0, 0.5, -0.2], 80.0, 0.4), MachineInput(jnp.zeros(4), 1.0)
    )
    A, B = np.asarray(A), np.asarray(B)
    R, L = float(motor.R), float(motor.L_ls)
    np.testing.assert_allclose(A[2:4, 2:4], -R / L * np.eye(2), rtol=1e-12)
    np.testing.assert_allclose(B[2:4, 2:4], np.eye(2) / L, rtol=1e-12)
    assert np.all(A[2:4, [0, 1, 4, 5]] == 0) and np.all(A[[0, 1, 4, 5]][:, 2:4] == 0)
    assert B.shape == (6, 5)


def test_parameter_and_layout_checks():
    with pytest.raises(ParameterError, match="L_ls"):
        MultiPhaseParameters(R=0.5, L_d=1e-3, L_q=1e-3, psi_f=0.1, L_ls=2e-3, J=1e-3, B=0.0)
    with pytest.raises(ParameterError, match="resistance_scale must have shape"):
        MultiPhasePMSMdq(six_phase_motor(), resistance_scale=(1.0, 1.0))
    five = PhaseLayout(tuple(2 * np.pi * k / 5 for k in range(5)), ((0, 1, 2, 3, 4),), (1, 3), "five-phase")
    with pytest.raises(ParameterError, match="n_phases = 6"):
        MultiPhasePMSMVSD(six_phase_motor(), layout=five)
    with pytest.raises(ParameterError, match="dual three-phase"):
        PMSM6DoubleDQ(six_phase_motor(), layout=five)
    assert MultiPhasePMSMdq(six_phase_motor()).n_phases == 6
    assert isinstance(MultiPhasePMSMdq(six_phase_motor()).initial_state(), MachineState)
