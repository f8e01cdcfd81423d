"""Replay of recorded voltages (pmsmjax.recorded.replay) and log I/O (pmsmjax.io.logs).

The reference is an adaptive scipy solve of the dq equations written here in NumPy, one solve per row
interval (the held voltage jumps at every row), with each hold frame spelled out independently.
"""

import os

import numpy as np
import pytest
import scipy.io
from scipy.integrate import solve_ivp

import pmsmjax.recorded.replay as replay_module
from pmsmjax.io.logs import atomic_write, read_log, write_csv_atomic
from pmsmjax.presets.three_phase import book_motor
from pmsmjax.recorded.replay import REPLAY_COLUMNS, default_substeps, replay, replay_file
from pmsmjax.spec.validation import ParameterError

# Book motors as plain numbers for the reference (salient: L_q = 12 mH).
SURFACE = dict(R=0.958, L_d=5.25e-3, L_q=5.25e-3, psi_f=0.1827, J=0.003, B=0.008, p=4)
SALIENT = dict(SURFACE, L_q=12e-3)


def reference(mp, t, u_dq, omega_m=None, load=None, hold="rotor", theta0=0.0, i0=(0.0, 0.0), w0=0.0):
    """Row-by-row solve_ivp (DOP853, rtol 1e-10) of the dq model; returns (N, 4) [i_d, i_q, w_m, th_e]."""
    R, Ld, Lq, psi, J, B, p = (mp[k] for k in ("R", "L_d", "L_q", "psi_f", "J", "B", "p"))
    n = len(t)
    load = np.zeros(n) if load is None else np.broadcast_to(load, (n,))
    y = np.array([i0[0], i0[1], omega_m[0] if omega_m is not None else w0, theta0], float)
    out = [y.copy()]
    for k in range(n - 1):
        if omega_m is not None:
            y[2] = omega_m[k]
        th_k = y[3]
        # Stator hold: the alpha-beta vector of u_dq[k] at the row's angle stays fixed.
        u_ab = np.array(
            [
                u_dq[k, 0] * np.cos(th_k) - u_dq[k, 1] * np.sin(th_k),
                u_dq[k, 0] * np.sin(th_k) + u_dq[k, 1] * np.cos(th_k),
            ]
        )

        def f(_, x, k=k, u_ab=u_ab):
            i_d, i_q, w, th = x
            if hold == "rotor":
                ud, uq = u_dq[k]
            else:
                ud = u_ab[0] * np.cos(th) + u_ab[1] * np.sin(th)
                uq = -u_ab[0] * np.sin(th) + u_ab[1] * np.cos(th)
            we = p * w
            did = (ud - R * i_d + we * Lq * i_q) / Ld
            diq = (uq - R * i_q - we * (Ld * i_d + psi)) / Lq
            te = 1.5 * p * (psi * i_q + (Ld - Lq) * i_d * i_q)
            dw = 0.0 if omega_m is not None else (te - load[k] - B * w) / J
            return [did, diq, dw, we]

        sol = solve_ivp(f, (t[k], t[k + 1]), y, method="DOP853", rtol=1e-10, atol=1e-12)
        y = sol.y[:, -1].copy()
        out.append(y.copy())
    out = np.array(out)
    if omega_m is not None:
        out[:, 2] = omega_m
    return out


def motor_of(mp):
    return book_motor(salient=mp["L_q"] != mp["L_d"])


def angle_err(a, b):
    return np.abs(np.angle(np.exp(1j * (np.asarray(a) - np.asarray(b)))))


def current_err(res, ref):
    """Max dq current error relative to the peak reference current magnitude."""
    err = np.hypot(res["i_d"] - ref[:, 0], res["i_q"] - ref[:, 1])
    return err.max() / np.hypot(ref[:, 0], ref[:, 1]).max()


def imposed_log(n=300, dt=1e-4, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    w = np.linspace(90.0, 115.0, n)  # imposed speed ramps: each row's value must be used
    u_d = -20.0 + 5.0 * np.sin(2 * np.pi * 50 * t) + rng.normal(0, 3, n)
    u_q = 80.0 + 10.0 * np.sin(2 * np.pi * 30 * t) + rng.normal(0, 3, n)
    return t, np.stack([u_d, u_q], 1), w


def dynamic_log(n=400, dt=1e-4, seed=1):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    u_q = np.minimum(t / 0.02, 1.0) * 40.0 + 5.0 + rng.normal(0, 2, n)
    u_d = -3.0 + rng.normal(0, 2, n)
    load = np.where(t > 0.02, 0.5, 0.0)
    return t, np.stack([u_d, u_q], 1), load


# --------------------------------------------------------------------------------------------------
# accuracy against solve_ivp
# --------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("hold", ["rotor", "stator"])
def test_imposed_speed_matches_solve_ivp(hold):
    t, u, w = imposed_log()
    res = replay(motor_of(SALIENT), t, u, omega_m=w, hold=hold, theta_e0=0.3, i_dq0=(1.0, 2.0))
    ref = reference(SALIENT, t, u, omega_m=w, hold=hold, theta0=0.3, i0=(1.0, 2.0))
    assert current_err(res, ref) < 1e-3
    assert angle_err(res["theta_e"], ref[:, 3]).max() < 1e-9
    np.testing.assert_array_equal(res["omega_m"], w)
    np.testing.assert_array_equal(res["time"], t)
    assert res["i_d"][0] == 1.0 and res["i_q"][0] == 2.0 and res["theta_e"][0] == 0.3


@pytest.mark.parametrize("hold", ["rotor", "stator"])
def test_dynamic_speed_matches_solve_ivp(hold):
    t, u, load = dynamic_log()
    res = replay(motor_of(SALIENT), t, u, load_torque=load, hold=hold, theta_e0=-1.0)
    ref = reference(SALIENT, t, u, load=load, hold=hold, theta0=-1.0)
    assert current_err(res, ref) < 1e-3
    assert np.abs(res["omega_m"] - ref[:, 2]).max() < 1e-3 * np.abs(ref[:, 2]).max()
    assert angle_err(res["theta_e"], ref[:, 3]).max() < 1e-3
    assert ref[-1, 2] > 20.0  # the machine did speed up, so the hold frames matter


def test_holds_differ_at_speed_and_each_matches_its_own_reference():
    """The reference test must be able to tell the holds apart: their gap is far above the tolerance."""
    t, u, w = imposed_log()
    m = motor_of(SURFACE)
    rotor = replay(m, t, u, omega_m=w, hold="rotor")
    stator = replay(m, t, u, omega_m=w, hold="stator")
    ref_stator = reference(SURFACE, t, u, omega_m=w, hold="stator")
    assert current_err(rotor, ref_stator) > 20 * current_err(stator, ref_stator)
    assert current_err(rotor, ref_stator) > 0.02


def test_zero_speed_holds_identical():
    t, u, _ = imposed_log(n=200)
    w = np.zeros_like(t)
    m = motor_of(SALIENT)
    rotor = replay(m, t, u, omega_m=w, hold="rotor", theta_e0=0.7)
    stator = replay(m, t, u, omega_m=w, hold="stator", theta_e0=0.7)
    for c in REPLAY_COLUMNS:
        np.testing.assert_allclose(stator[c], rotor[c], rtol=1e-12, atol=1e-12)
    assert np.abs(rotor["i_q"]).max() > 10.0  # currents flowed: the comparison is not trivially 0 == 0


def test_irregular_time_grid():
    rng = np.random.default_rng(3)
    n = 120
    dt = rng.uniform(0.2e-4, 3e-3, n - 1)
    t = np.concatenate([[0.5], 0.5 + np.cumsum(dt)])
    w = np.full(n, 104.7)
    u = np.stack([rng.normal(-15, 5, n), rng.normal(80, 5, n)], 1)
    m = motor_of(SURFACE)
    # Longest interval (near 3 ms) at omega_e = 419 rad/s needs several sub-steps.
    assert default_substeps(m, dt.max(), 104.7) >= 3
    for hold in ("rotor", "stator"):
        res = replay(m, t, u, omega_m=w, hold=hold)
        ref = reference(SURFACE, t, u, omega_m=w, hold=hold)
        assert len(res["time"]) == n
        assert current_err(res, ref) < 1e-3


# --------------------------------------------------------------------------------------------------
# bad input: errors before compiling, no output left behind
# --------------------------------------------------------------------------------------------------
def write_log(path, header, rows):
    path.write_text(header + "\n" + "\n".join(",".join(str(x) for x in r) for r in rows) + "\n")
    return path


def good_rows(n=20):
    t, u, _ = imposed_log(n=n)
    return [[t[k], u[k, 0], u[k, 1]] for k in range(n)]


@pytest.fixture
def no_compile(monkeypatch):
    """Fail the test if the simulation core is reached: bad input must be caught before compiling."""

    def boom(*args, **kwargs):
        raise AssertionError("replay_scan was called: input was not checked before compiling")

    monkeypatch.setattr(replay_module, "replay_scan", boom)


def assert_no_output(out):
    assert not (out / "replay.csv").exists()
    if out.exists():
        assert os.listdir(out) == []


def test_missing_column(tmp_path, no_compile):
    log = write_log(tmp_path / "log.csv", "time,u_d,uq", good_rows())
    out = tmp_path / "out"
    with pytest.raises(ParameterError, match="u_q") as err:
        replay_file(log, "book", out)
    msg = str(err.value)
    assert "present: time, u_d, uq" in msg and "rename" in msg
    assert_no_output(out)


def test_nan_names_column_and_row(tmp_path, no_compile):
    rows = good_rows()
    rows[5][2] = "nan"
    log = write_log(tmp_path / "log.csv", "time,u_d,u_q", rows)
    out = tmp_path / "out"
    with pytest.raises(ParameterError, match=r"'u_q' is NaN .* at row 5 \(file line 7\)"):
        replay_file(log, "book", out)
    assert_no_output(out)
    # An empty field is reported the same way.
    rows = good_rows()
    rows[3][1] = ""
    log = write_log(tmp_path / "log2.csv", "time,u_d,u_q", rows)
    with pytest.raises(ParameterError, match=r"'u_d' is NaN .* at row 3"):
        replay_file(log, "book", out)
    # And from Python with arrays.
    t, u, w = imposed_log(n=20)
    w[4] = np.inf
    with pytest.raises(ParameterError, match=r"'omega_m' is inf .* at row 4"):
        replay(book_motor(), t, u, omega_m=w)
    assert_no_output(out)


def test_non_increasing_time(tmp_path, no_compile):
    rows = good_rows()
    rows[7][0] = rows[6][0]
    log = write_log(tmp_path / "log.csv", "time,u_d,u_q", rows)
    out = tmp_path / "out"
    with pytest.raises(ParameterError, match=r"strictly increasing but row 7 \(file line 9\)"):
        replay_file(log, "book", out)
    assert_no_output(out)
    t, u, _ = imposed_log(n=20)
    with pytest.raises(ParameterError, match="strictly increasing but row 1"):
        replay(book_motor(), t[::-1], u)


def test_too_few_rows(tmp_path, no_compile):
    log = write_log(tmp_path / "log.csv", "time,u_d,u_q", good_rows()[:1])
    with pytest.raises(ParameterError, match="at least 2 rows"):
        replay_file(log, "book", tmp_path / "out")
    assert_no_output(tmp_path / "out")


@pytest.mark.parametrize("R", ["0.0", "-1.0"])
def test_non_physical_motor_toml(tmp_path, no_compile, R):
    log = write_log(tmp_path / "log.csv", "time,u_d,u_q", good_rows())
    toml = tmp_path / "motor.toml"
    toml.write_text(f"R = {R}\nL_d = 5e-3\nL_q = 5e-3\npsi_f = 0.18\npole_pairs = 4\nJ = 0.003\nB = 0.0\n")
    out = tmp_path / "out"
    with pytest.raises(ParameterError, match=r"\[motor\] R = -?[01] ohm: give a value > 0"):
        replay_file(log, toml, out)
    assert_no_output(out)


def test_n_substeps_too_small(tmp_path, no_compile):
    t = np.arange(20) * 3e-3
    u = np.tile([-10.0, 80.0], (20, 1))
    w = np.full(20, 104.7)
    with pytest.raises(ParameterError, match=r"set n_substeps >= 3"):
        replay(book_motor(), t, u, omega_m=w, n_substeps=1)
    with pytest.raises(ParameterError, match="n_substeps must be a positive int"):
        replay(book_motor(), t, u, omega_m=w, n_substeps=0)
    np.savez(tmp_path / "log.npz", time=t, u_d=u[:, 0], u_q=u[:, 1], omega_m=w)
    out = tmp_path / "out"
    with pytest.raises(ParameterError, match="n_substeps"):
        replay_file(tmp_path / "log.npz", "book", out, n_substeps=2)
    assert_no_output(out)


def test_bad_hold_and_shapes(no_compile):
    t, u, _ = imposed_log(n=10)
    with pytest.raises(ParameterError, match="hold must be"):
        replay(book_motor(), t, u, hold="alpha_beta")
    with pytest.raises(ParameterError, match=r"u_dq must have shape \(N, 2\)"):
        replay(book_motor(), t, u.T)
    with pytest.raises(ParameterError, match="different lengths"):
        replay(book_motor(), t[:-1], u)


def test_failed_replay_keeps_previous_output(tmp_path):
    t, u, w = imposed_log(n=30)
    log = tmp_path / "log.csv"
    write_csv_atomic(log, {"time": t, "u_d": u[:, 0], "u_q": u[:, 1], "omega_m": w})
    out = tmp_path / "out"
    first = replay_file(log, "book", out).read_bytes()
    bad = write_log(tmp_path / "bad.csv", "time,u_d", good_rows())
    with pytest.raises(ParameterError):
        replay_file(bad, "book", out)
    assert (out / "replay.csv").read_bytes() == first
    assert os.listdir(out) == ["replay.csv"]


def test_atomic_write_interrupted(tmp_path):
    target = tmp_path / "data.csv"
    target.write_text("old\n")

    def writer(f):
        f.write(b"half a fil")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        atomic_write(target, writer)
    assert target.read_text() == "old\n"
    assert os.listdir(tmp_path) == ["data.csv"]
    atomic_write(target, lambda f: f.write("new\n"), mode="w")
    assert target.read_text() == "new\n"
    assert os.listdir(tmp_path) == ["data.csv"]


# --------------------------------------------------------------------------------------------------
# file round trip and formats
# --------------------------------------------------------------------------------------------------
def test_csv_round_trip_and_formats(tmp_path):
    t, u, w = imposed_log(n=50)
    theta0, i0 = 1.1, (-0.5, 2.5)
    i_d = np.full(50, i0[0])
    i_q = np.full(50, i0[1])
    theta = np.full(50, theta0)
    # CSV written with numpy: spaces after commas and an extra unknown column are tolerated.
    csv = tmp_path / "log.csv"
    table = np.stack([t, u[:, 0], u[:, 1], w, theta, i_d, i_q, np.arange(50.0)], 1)
    np.savetxt(
        csv,
        table,
        fmt="%.17g",
        delimiter=", ",
        header="time, u_d, u_q, omega_m, theta_e, i_d, i_q, extra",
        comments="",
    )
    cols = dict(time=t, u_d=u[:, 0], u_q=u[:, 1], omega_m=w, theta_e=theta, i_d=i_d, i_q=i_q)
    np.savez(tmp_path / "log.npz", **cols)
    # MATLAB stores vectors as (N, 1) columns.
    scipy.io.savemat(tmp_path / "log.mat", {k: v[:, None] for k, v in cols.items()})

    results = {}
    for name in ("log.csv", "log.npz", "log.mat"):
        path = replay_file(
            tmp_path / name, "book", tmp_path / name.replace(".", "_") / "nested", hold="stator"
        )
        assert path.name == "replay.csv" and path.is_file()
        header = path.read_text().splitlines()[0]
        assert header == "time,i_d,i_q,omega_m,theta_e"
        data = read_log(path, REPLAY_COLUMNS)
        assert all(len(v) == 50 for v in data.values())
        results[name] = data
    for name in ("log.npz", "log.mat"):
        for c in REPLAY_COLUMNS:
            np.testing.assert_array_equal(results[name][c], results["log.csv"][c])

    direct = replay(book_motor(), t, u, omega_m=w, hold="stator", theta_e0=theta0, i_dq0=i0)
    for c in REPLAY_COLUMNS:
        np.testing.assert_array_equal(results["log.csv"][c], direct[c])  # %.17g round trips exactly
    row0 = results["log.csv"]
    assert (row0["i_d"][0], row0["i_q"][0], row0["theta_e"][0], row0["omega_m"][0]) == (*i0, theta0, w[0])


def test_motor_toml_and_dynamic_log(tmp_path):
    """A TOML motor equal to the book motor gives the preset's result; no omega_m column -> dynamic speed."""
    t, u, load = dynamic_log(n=100)
    log = tmp_path / "log.csv"
    write_csv_atomic(log, {"time": t, "u_d": u[:, 0], "u_q": u[:, 1], "T_L": load})
    toml = tmp_path / "motor.toml"
    toml.write_text(
        "[motor]\nR = 0.958\nL_d = 5.25e-3\nL_q = 5.25e-3\npsi_f = 0.1827\npole_pairs = 4\n"
        "J = 0.003\nB = 0.008\n"
    )
    # hold="rotor" spelled out: replay_file's default is "auto", which has no currents in
    # this log to decide from and falls back on "stator"; the reference below holds in the rotor frame.
    a = read_log(replay_file(log, toml, tmp_path / "a", hold="rotor"), REPLAY_COLUMNS)
    b = read_log(replay_file(log, "book", tmp_path / "b", hold="rotor"), REPLAY_COLUMNS)
    for c in REPLAY_COLUMNS:
        np.testing.assert_array_equal(a[c], b[c])
    ref = reference(SURFACE, t, u, load=load)
    assert current_err(a, ref) < 1e-3
    assert a["omega_m"][-1] > 1.0


def test_read_log_errors(tmp_path):
    with pytest.raises(ParameterError, match="does not exist"):
        read_log(tmp_path / "nope.csv")
    (tmp_path / "log.xlsx").write_text("x")
    with pytest.raises(ParameterError, match="unknown format"):
        read_log(tmp_path / "log.xlsx")
    np.savez(tmp_path / "log.npz", time=np.arange(5.0), u_d=np.zeros(4))
    with pytest.raises(ParameterError, match="different lengths"):
        read_log(tmp_path / "log.npz", ("time", "u_d"))
    np.savez(tmp_path / "log2.npz", time=np.arange(5.0), u_d=np.zeros((5, 2)))
    with pytest.raises(ParameterError, match="must be a vector"):
        read_log(tmp_path / "log2.npz", ("time", "u_d"))
    (tmp_path / "nohead.csv").write_text("0,1,2\n1,1,2\n")
    with pytest.raises(ParameterError, match="not a header"):
        read_log(tmp_path / "nohead.csv")
    (tmp_path / "ragged.csv").write_text("time,u_d\n0,1\n1,2,3\n")
    with pytest.raises(ParameterError, match="line 3: 3 fields"):
        read_log(tmp_path / "ragged.csv", ("time", "u_d"))
    # Comments and blank lines are skipped; optional columns only when present; extras ignored.
    (tmp_path / "ok.csv").write_text("# exported\n\n time , u_d ,x\n0, 1 ,9\n\n1,2,9\n")
    got = read_log(tmp_path / "ok.csv", ("time", "u_d"), ("omega_m",))
    assert list(got) == ["time", "u_d"]
    np.testing.assert_array_equal(got["u_d"], [1.0, 2.0])
    # Time check can be switched off for logs without a time column.
    (tmp_path / "notime.csv").write_text("a\n2\n1\n")
    assert read_log(tmp_path / "notime.csv", ("a",), time=None)["a"].tolist() == [2.0, 1.0]


@pytest.mark.slow
def test_replay_scan_gradient_matches_finite_differences():
    """The core scan is differentiable in the motor parameters (what identification from logs needs)."""
    import equinox as eqx
    import jax.numpy as jnp
    from helpers.gradient_check import check_gradient

    from pmsmjax.machines import PMSMdq

    t, u, w = imposed_log(n=60)
    dt, u_k, w_k = jnp.asarray(np.diff(t)), jnp.asarray(u[:-1]), jnp.asarray(w[:-1])

    def loss(params, hold):
        motor = eqx.tree_at(lambda m: (m.R, m.psi_f), book_motor(), (params[0], params[1]))
        machine = PMSMdq(motor, mechanics="imposed")
        states = replay_module.replay_scan(
            machine, machine.initial_state(), dt, u_k, w_k, jnp.zeros_like(dt), 1, hold
        )
        return jnp.mean(states.currents**2)

    x = jnp.array([0.958, 0.1827])
    for hold in ("rotor", "stator"):
        r = check_gradient(
            lambda p, hold=hold: loss(p, hold), x, rel_step=1e-6, rtol=1e-6, labels=["R", "psi_f"]
        )
        assert np.all(np.abs(r.grad) > 1e-3)


def test_dynamic_speed_substeps_follow_the_reached_speed(monkeypatch):
    """If the dynamic run outruns the speed estimate, the default sub-step count is raised and rerun."""
    t, u, load = dynamic_log(n=40, dt=5e-3)
    m = motor_of(SURFACE)
    honest = replay(m, t, u, load_torque=load)
    reached = np.abs(honest["omega_m"]).max()
    n_final = default_substeps(m, 5e-3, reached)
    assert n_final > default_substeps(m, 5e-3, 1.0)  # the low estimate below really is too low

    calls = []
    real_scan = replay_module.replay_scan
    monkeypatch.setattr(replay_module, "_dynamic_speed_bound", lambda *a: 1.0)
    monkeypatch.setattr(replay_module, "replay_scan", lambda *a: calls.append(a[-2]) or real_scan(*a))
    res = replay(m, t, u, load_torque=load)
    assert calls[-1] == n_final and len(calls) >= 2
    explicit = replay(m, t, u, load_torque=load, n_substeps=n_final)
    for c in REPLAY_COLUMNS:
        np.testing.assert_array_equal(res[c], explicit[c])
    assert current_err(res, reference(SURFACE, t, u, load=load)) < 1e-3
    # A user-given count that only looked stable for the estimate is run as given, with a warning.
    with pytest.warns(UserWarning, match="raise n_substeps"):
        replay(m, t, u, load_torque=load, n_substeps=n_final - 1)
