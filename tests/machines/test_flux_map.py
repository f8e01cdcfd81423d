"""The flux-map machine (pmsmjax/machines/flux_map.py, pmsm_flux_map.py) and its files
(pmsmjax/io/flux_map_files.py) against independent references.

- A map sampled from the linear model reproduces the linear dq machine in a closed-loop book run.
- A map sampled from an analytic saturation model with cross-saturation (written out here, with closed-form
  flux and co-energy) follows a scipy ``solve_ivp`` solution of the same analytic model.
- Power balance over a run, the field energy from the map's co-energy by quadrature.
- Gradients through a run are finite and agree with central differences.
- The map's checks and the readers refuse careless maps in one line.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers.gradient_check import check_gradient
from scipy.integrate import solve_ivp

from pmsmjax.io.flux_map_files import read_flux_map, write_flux_map_csv
from pmsmjax.machines import MachineInput, MachineState, advance
from pmsmjax.machines.flux_map import FluxMapGrid
from pmsmjax.machines.pmsm_flux_map import FluxMap, PMSMFluxMapdq, flux_map_machine
from pmsmjax.presets.three_phase import book_drive, book_motor
from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.simulate import simulate
from pmsmjax.spec.validation import ParameterError

# --- the analytic saturation model (independent of the package) --------------------------------------
# One iron path saturating with the total ampere-turns: co-energy per 1.5 factor
#   W'(i) = L_dl i_d^2/2 + L_ql i_q^2/2 + L_m s^2 ln cosh(r/s),  r = sqrt(s0^2 + (i_d + i0)^2 + (k i_q)^2),
# i0 the magnet's equivalent d current. psi = grad W': the q current saturates the d path (cross-saturation)
# and the magnet's bias saturates the q path; the Hessian is positive definite (a convex function of a norm
# plus the leakage terms) and the map reciprocal.
M = dict(L_dl=2e-3, L_ql=4e-3, L_m=12e-3, s=15.0, s0=5.0, i0=20.0, k=1.2)
R, P_N, J_ROT, B_ROT = 0.958, 4, 0.003, 0.008


def _r(i_d, i_q):
    return np.sqrt(M["s0"] ** 2 + (i_d + M["i0"]) ** 2 + (M["k"] * i_q) ** 2)


def psi_analytic(i_d, i_q):
    r = _r(i_d, i_q)
    g = M["L_m"] * M["s"] * np.tanh(r / M["s"]) / r
    return M["L_dl"] * i_d + g * (i_d + M["i0"]), M["L_ql"] * i_q + g * M["k"] ** 2 * i_q


def coenergy_analytic(i_d, i_q):
    r = _r(i_d, i_q)
    return (
        0.5 * M["L_dl"] * i_d**2
        + 0.5 * M["L_ql"] * i_q**2
        + M["L_m"] * M["s"] ** 2 * np.log(np.cosh(r / M["s"]))
    )


def inductance_analytic(i_d, i_q, h=1e-6):
    cols = [
        (
            np.array(psi_analytic(i_d + h * e0, i_q + h * e1))
            - np.array(psi_analytic(i_d - h * e0, i_q - h * e1))
        )
        / (2 * h)
        for e0, e1 in ((1, 0), (0, 1))
    ]
    return np.stack(cols, -1)


def analytic_grid(n, span=40.0):
    axis = np.linspace(-span, span, n)
    D, Q = np.meshgrid(axis, axis, indexing="ij")
    return FluxMapGrid(axis, axis, *psi_analytic(D, Q), source="analytic map")


def linear_grid(motor, n=7, span=40.0):
    axis = np.linspace(-span, span, n)
    D, Q = np.meshgrid(axis, axis, indexing="ij")
    return FluxMapGrid(axis, axis, float(motor.L_d) * D + float(motor.psi_f), float(motor.L_q) * Q)


def test_analytic_model_is_its_coenergys_gradient():
    # the written-out flux is the gradient of the written-out co-energy (guards the reference itself)
    h = 1e-5
    for i_d, i_q in ((3.0, -7.0), (-25.0, 30.0)):
        fd = [(coenergy_analytic(i_d + h, i_q) - coenergy_analytic(i_d - h, i_q)) / (2 * h),
              (coenergy_analytic(i_d, i_q + h) - coenergy_analytic(i_d, i_q - h)) / (2 * h)]  # fmt: skip
        np.testing.assert_allclose(psi_analytic(i_d, i_q), fd, rtol=1e-8)


# --- the interpolant ------------------------------------------------------------------------------------
def test_interpolant_exact_on_bilinear_and_c1():
    axis = np.linspace(-10.0, 10.0, 5)
    D, Q = np.meshgrid(axis, axis, indexing="ij")
    grid = FluxMapGrid(axis, axis, 0.1 + 5e-3 * D + 2e-4 * D * Q, 9e-3 * Q + 1e-4 * D * Q)
    fm = FluxMap.from_grid(grid)
    for i in ((1.3, -2.2), (-9.9, 9.9), (4.99999, 0.0)):
        psi, L = fm(jnp.asarray(i))
        d, q = i
        np.testing.assert_allclose(psi, [0.1 + 5e-3 * d + 2e-4 * d * q, 9e-3 * q + 1e-4 * d * q], atol=1e-15)
        np.testing.assert_allclose(L, [[5e-3 + 2e-4 * q, 2e-4 * d], [1e-4 * q, 9e-3 + 1e-4 * d]], atol=1e-15)
    # on the saturated map: L_inc is the flux's gradient and continuous across a cell edge (5.0 A)
    fm = FluxMap.from_grid(analytic_grid(9))
    L_left = fm(jnp.array([0.0 - 1e-9, 3.0]))[1]
    L_right = fm(jnp.array([0.0 + 1e-9, 3.0]))[1]
    np.testing.assert_allclose(L_left, L_right, atol=1e-10)
    jac = jax.jacfwd(lambda i: fm(i)[0])(jnp.array([2.7, -4.1]))
    np.testing.assert_allclose(jac, fm(jnp.array([2.7, -4.1]))[1], rtol=1e-12)


def test_linear_extension_outside_the_grid():
    fm = FluxMap.from_grid(analytic_grid(9))
    edge = jnp.array([40.0, 12.0])
    psi_e, L_e = fm(edge)
    psi, L = fm(edge + jnp.array([6.0, 0.0]))
    np.testing.assert_allclose(psi, psi_e + L_e @ jnp.array([6.0, 0.0]), rtol=1e-14)
    np.testing.assert_allclose(L, L_e, rtol=1e-14)
    report = fm.excursion(np.array([[0.0, 0.0], [46.0, 12.0], [-10.0, -41.0]]))
    assert report["outside_a"] == pytest.approx(6.0) and "6 A" in report["warning"]
    assert fm.excursion(np.zeros((3, 2)))["warning"] is None


# --- the plant ------------------------------------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("which", ["saturated-ipm", "analytic"])
def test_numpy_and_jax_interpolants_agree(which):
    """One interpolant, two namespaces: NumPy on a batch of points (the checks before a run) gives, point
    by point, what NumPy gives on each point alone, bit for bit, and what the plant's JAX gives on it to
    float64 rounding (XLA orders the coefficients' einsum and may fuse a product into a sum), inside the
    grid and outside it (the linear extension)."""
    if which == "saturated-ipm":
        from pmsmjax.io.drive_files import PRESET_FOLDER

        grid = read_flux_map(PRESET_FOLDER / "saturated_ipm_map.csv")
    else:
        grid = analytic_grid(9)
    rng = np.random.default_rng(7)
    span = 1.5 * np.maximum(np.abs(grid.lower), np.abs(grid.upper))
    points = rng.uniform(-span, span, (400, 2))
    points[:4] = [grid.lower, grid.upper, [grid.i_d[1], grid.i_q[-2]], [0.0, 0.0]]  # nodes and corners
    psi, L = grid.flux(points)
    assert psi.shape == (400, 2) and L.shape == (400, 2, 2)
    outside = np.any((points < grid.lower) | (points > grid.upper), axis=1)
    assert 50 < outside.sum() < 350
    single = [grid.at(*p) for p in points[:50]]
    assert all(np.array_equal(a, psi[k]) and np.array_equal(b, L[k]) for k, (a, b) in enumerate(single))
    plant = FluxMap.from_grid(grid)
    at = jax.jit(lambda i: plant(i))
    psi_j, L_j = (np.stack(x) for x in zip(*[at(jnp.asarray(p)) for p in points], strict=True))
    scale_psi = max(np.abs(grid.psi_d).max(), np.abs(grid.psi_q).max())
    scale_L = np.abs(grid.node_inductances()).max()
    assert np.abs(psi - psi_j).max() <= 1e-12 * scale_psi
    assert np.abs(L - L_j).max() <= 1e-12 * scale_L


def test_linear_map_reproduces_the_linear_machine():
    drive = book_drive(book_motor(salient=True))
    motor = drive.machine.motor
    plant = PMSMFluxMapdq(motor, FluxMap.from_grid(linear_grid(motor)))
    scenario = Scenario(
        duration_s=0.03, speed_ref=Profile.constant(100.0), load_torque=Profile.step(0.02, 0.0, 3.0)
    )
    linear = simulate(drive, scenario)
    mapped = simulate(eqx.tree_at(lambda d: d.machine, drive, plant), scenario)
    assert np.abs(linear.i_dq).max() > 5.0  # the run exercises the currents
    for name in ("i_dq", "omega_m", "torque"):
        np.testing.assert_allclose(getattr(mapped, name), getattr(linear, name), rtol=0, atol=1e-11)


def _rhs(t, x, u_ab):
    i_d, i_q, w_m, th = x
    c, s = np.cos(th), np.sin(th)
    u = np.array([u_ab[0] * c + u_ab[1] * s, -u_ab[0] * s + u_ab[1] * c])
    w_e = P_N * w_m
    psi = np.array(psi_analytic(i_d, i_q))
    di = np.linalg.solve(
        inductance_analytic(i_d, i_q), u - R * np.array([i_d, i_q]) - w_e * np.array([-psi[1], psi[0]])
    )
    T_e = 1.5 * P_N * (psi[0] * i_q - psi[1] * i_d)
    return [di[0], di[1], (T_e - B_ROT * w_m) / J_ROT, w_e]


def _open_loop(machine, u_ab, Ts, n_sub, x0):
    def body(state, u):
        nxt = advance(machine, state, MachineInput(u, jnp.asarray(0.0)), Ts, n_sub)
        return nxt, jnp.concatenate([nxt.currents, nxt.omega_m[None]])

    s0 = MachineState(jnp.asarray(x0[:2]), jnp.asarray(x0[2]), jnp.asarray(x0[3]))
    return np.asarray(jax.lax.scan(body, s0, jnp.asarray(u_ab))[1])


@pytest.mark.parametrize("frame", ["stator", "rotor"])
@pytest.mark.parametrize("mechanics", ["dynamic", "imposed"])
def test_packed_integration_is_the_classical_rk4(frame, mechanics):
    # The plant integrates a packed state (advance_packed); the generic RK4 of its vector
    # field (integrate.rk4_step_rotating_hold for a stator-held voltage, rk4_step otherwise) is the reference.
    from pmsmjax.frames.three_phase import wrap_angle
    from pmsmjax.machines.integrate import rk4_step, rk4_step_rotating_hold

    machine = flux_map_machine(analytic_grid(GRID_POINTS), R, J_ROT, B_ROT, P_N, mechanics=mechanics)
    state = MachineState(jnp.asarray([-12.0, 25.0]), jnp.asarray(150.0), jnp.asarray(2.9))
    inputs = MachineInput(jnp.asarray([60.0, -90.0]), jnp.asarray(3.0), frame)
    Ts, n_sub = 1e-4, 7
    out = advance(machine, state, inputs, Ts, n_sub)
    ref, u = state, inputs.dq(state.theta_e)
    for _ in range(n_sub):
        if frame == "stator":
            ref, u = rk4_step_rotating_hold(machine, ref, u, inputs.load_torque, Ts / n_sub)
        else:
            ref = rk4_step(machine, ref, inputs, Ts / n_sub)
    assert abs(float(ref.currents[0]) - float(state.currents[0])) > 1.0  # the currents moved
    np.testing.assert_allclose(out.currents, ref.currents, rtol=0, atol=1e-11)
    np.testing.assert_allclose(out.omega_m, ref.omega_m, rtol=1e-13)
    np.testing.assert_allclose(out.theta_e, wrap_angle(ref.theta_e), rtol=1e-13)


def test_saturated_map_against_solve_ivp():
    rng = np.random.default_rng(5)
    Ts, n = 1e-4, 200
    u_ab = np.repeat(rng.uniform(-80.0, 80.0, size=(n // 5, 2)), 5, axis=0)  # steps every 5 periods
    x0 = np.array([0.0, 0.0, 20.0, 0.3])
    ref = np.empty((n + 1, 4))
    ref[0] = x = x0
    for k in range(n):
        sol = solve_ivp(_rhs, (0, Ts), x, args=(u_ab[k],), method="DOP853", rtol=1e-10, atol=1e-12)
        ref[k + 1] = x = sol.y[:, -1]
    machine = flux_map_machine(analytic_grid(GRID_POINTS), R, J_ROT, B_ROT, P_N)
    out = _open_loop(machine, u_ab, Ts, 8, x0)
    i_peak = np.abs(ref[:, :2]).max()
    assert 20.0 < i_peak < 40.0  # deep into saturation, inside the grid
    err = np.abs(out[:, :2] - ref[1:, :2]).max() / i_peak
    print(f"41-point map: {err:.2e} of the peak current")
    assert err < 1e-4
    # the interpolation error is what is measured: a 4x coarser grid misses the bound
    coarse = _open_loop(flux_map_machine(analytic_grid(11), R, J_ROT, B_ROT, P_N), u_ab, Ts, 8, x0)
    err_coarse = np.abs(coarse[:, :2] - ref[1:, :2]).max() / i_peak
    print(f"11-point map: {err_coarse:.2e} of the peak current")
    assert err_coarse > 1e-4


#: Points per axis of the saturated test map over +-40 A (2 A steps): the finest of 11, 21, 41 that keeps
#: the open-loop run within 1e-4 of the peak current.
GRID_POINTS = 41


def test_power_balance_from_the_maps_coenergy():
    grid = analytic_grid(GRID_POINTS)
    machine = flux_map_machine(grid, R, J_ROT, B_ROT, P_N, mechanics="imposed")
    fm = machine.flux_map
    h, n = 2e-6, 4000
    t = np.arange(n) * h
    u_dq = np.stack([40.0 * np.sin(2e3 * t) - 10.0, 90.0 * np.cos(900.0 * t) + 30.0], -1)

    def body(state, u):
        nxt = advance(machine, state, MachineInput(u, jnp.asarray(0.0), "rotor"), h, 1)
        return nxt, nxt.currents

    s0 = machine.initial_state((-3.0, 2.0), 150.0, 0.0)
    i = np.concatenate(
        [np.asarray(s0.currents)[None], np.asarray(jax.lax.scan(body, s0, jnp.asarray(u_dq))[1])]
    )
    # u held over each step; evaluate the powers at the step's ends and integrate by the trapezoid rule
    psi = np.asarray(jax.vmap(machine.flux_dq)(jnp.asarray(i)))
    torque = 1.5 * P_N * (psi[:, 0] * i[:, 1] - psi[:, 1] * i[:, 0])
    w_m = 150.0
    p_in = 1.5 * np.einsum("kj,kj->k", u_dq, 0.5 * (i[:-1] + i[1:]))
    p_loss = 1.5 * R * 0.5 * ((i[:-1] ** 2).sum(1) + (i[1:] ** 2).sum(1))
    p_mech = 0.5 * (torque[:-1] + torque[1:]) * w_m
    work = np.sum((p_in - p_loss - p_mech) * h)

    def field_energy(i_dq):
        # W = 1.5 (psi.i - W'/1.5), co-energy by 64-point Gauss-Legendre along the ray from zero current
        x, w = np.polynomial.legendre.leggauss(64)
        tau = 0.5 * (x + 1.0)
        rays = jnp.asarray(tau[:, None] * i_dq[None, :])
        psi_ray = np.asarray(jax.vmap(lambda c: fm(c)[0])(rays))
        coenergy = 0.5 * np.sum(w * (psi_ray @ i_dq))
        return 1.5 * (np.asarray(fm(jnp.asarray(i_dq))[0]) @ i_dq - coenergy)

    dW = field_energy(i[-1]) - field_energy(i[0])
    assert np.abs(i).max() > 20.0  # saturating currents
    exchanged = np.sum(np.abs(p_in) * h)
    print(f"power balance: {abs(work - dW) / exchanged:.2e} of the energy exchanged")
    assert abs(work - dW) < 1e-5 * exchanged, (work, dW, exchanged)
    # and the map's co-energy is the analytic one to the grid's interpolation error (4e-5 measured)
    i_end = i[-1]
    W_ref = 1.5 * (
        np.dot(psi_analytic(*i_end), i_end) - coenergy_analytic(*i_end) + coenergy_analytic(0.0, 0.0)
    )
    assert abs(field_energy(i_end) - W_ref) < 1e-4 * abs(W_ref)


@pytest.mark.slow
def test_gradients_through_a_run():
    grid = analytic_grid(21)
    base = flux_map_machine(grid, R, J_ROT, B_ROT, P_N)

    def final_speed(r, u_amp):
        m = eqx.tree_at(lambda x: x.motor.R, base, r)
        s0 = m.initial_state((0.0, 0.0), 10.0, 0.1)

        def body(state, k):
            u = u_amp * jnp.stack([jnp.cos(0.3 * k), jnp.sin(0.3 * k)])
            # one RK4 sub-step per 0.1 ms step: the claim is about differentiating through the run, and
            # each further sub-step adds about 12 s to the compilation of the reverse-mode program
            return advance(m, state, MachineInput(u, jnp.asarray(0.2)), 1e-4, 1), None

        return jax.lax.scan(body, s0, jnp.arange(30.0))[0].omega_m

    draws = jnp.asarray(np.random.default_rng(1).uniform([0.5, 30.0], [1.5, 90.0], size=(4, 2)))
    grads = jax.vmap(jax.grad(final_speed, argnums=(0, 1)))(draws[:, 0], draws[:, 1])
    assert all(np.all(np.isfinite(g)) and np.all(np.abs(g) > 0) for g in grads)
    # the vmapped gradient of draw 0 against central differences of the compiled run
    run = jax.jit(lambda x: final_speed(x[0], x[1]))
    first = np.array([g[0] for g in grads])
    check_gradient(run, np.asarray(draws[0]), grad=first, rel_step=1e-6, rtol=1e-5, labels=["R", "u_amp"])


# --- checks and files -----------------------------------------------------------------------------------
def _grid_arrays(n=5):
    axis = np.linspace(-10.0, 10.0, n)
    D, Q = np.meshgrid(axis, axis, indexing="ij")
    return axis, axis.copy(), 0.1 + 5e-3 * D, 9e-3 * Q


@pytest.mark.parametrize(
    "change, match",
    [
        (lambda a: (a[0][::-1], *a[1:]), "increase strictly"),
        (lambda a: (np.array([-10, -6, 0, 5, 10.0]), *a[1:]), "uniformly spaced"),
        (lambda a: (*a[:2], np.where(np.eye(5, dtype=bool), np.nan, a[2]), a[3]), "not finite"),
        (lambda a: (*a[:2], -a[2], a[3]), "psi_d does not rise with i_d"),
        (
            lambda a: (*a[:2], a[2] + 0.02 * a[1][None, :], a[3] + 0.02 * a[0][:, None]),
            "not positive definite",
        ),
        (lambda a: (a[0], a[1][:2], a[2][:, :2], a[3][:, :2]), "at least 3"),
    ],
)
def test_grid_checks(change, match):
    with pytest.raises(ParameterError, match=match):
        FluxMapGrid(*change(_grid_arrays()), source="map.csv")


def test_readers_agree_and_refuse(tmp_path):
    grid = analytic_grid(9)
    path = write_flux_map_csv(tmp_path / "map.csv", grid, header="analytic map")
    lines = path.read_text().splitlines()
    shuffled = tmp_path / "shuffled.csv"
    body = lines[2:]
    np.random.default_rng(0).shuffle(body)
    shuffled.write_text(
        "\n".join(["i_q,psi_q,i_d,psi_d"] + [",".join(np.array(r.split(","))[[1, 3, 0, 2]]) for r in body])
    )
    np.savez(tmp_path / "map.npz", i_d=grid.i_d, i_q=grid.i_q, psi_d=grid.psi_d, psi_q=grid.psi_q)
    D, Q = np.meshgrid(grid.i_d, grid.i_q, indexing="ij")
    np.savez(tmp_path / "complex.npz", i_s_dq=(D + 1j * Q).T, psi_s_dq=(grid.psi_d + 1j * grid.psi_q).T)
    from scipy.io import savemat

    savemat(
        tmp_path / "map.mat", {"i_d": grid.i_d, "i_q": grid.i_q, "psi_d": grid.psi_d, "psi_q": grid.psi_q}
    )
    for name in ("map.csv", "shuffled.csv", "map.npz", "complex.npz", "map.mat"):
        read = read_flux_map(tmp_path / name)
        for field in ("i_d", "i_q", "psi_d", "psi_q"):
            np.testing.assert_array_equal(getattr(read, field), getattr(grid, field), err_msg=name)

    careless = {
        "missing.csv": ("i_d,i_q,psi_d\n1,2,3\n", "lacks the column.*psi_q"),
        "holes.csv": ("\n".join(lines[1:-1]), "do not fill"),
        "nan.csv": ("\n".join(lines[1:5] + ["nan,nan,0.1,0.1"] + lines[6:]), "NaN"),
        "ma.csv": (
            "\n".join(
                [lines[1]]
                + [
                    ",".join(
                        [repr(1e3 * float(r.split(",")[0])), repr(1e3 * float(r.split(",")[1]))]
                        + r.split(",")[2:]
                    )
                    for r in lines[2:]
                ]
            ),
            "mA",
        ),
    }
    for name, (text, match) in careless.items():
        (tmp_path / name).write_text(text)
        with pytest.raises(ParameterError, match=match):
            read_flux_map(tmp_path / name)
    np.savez(tmp_path / "partial.npz", i_d=grid.i_d, psi_d=grid.psi_d)
    with pytest.raises(ParameterError, match="lacks the array"):
        read_flux_map(tmp_path / "partial.npz")
