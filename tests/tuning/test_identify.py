"""Identification of motor parameters from logs (the package tuning/identify/).

The logs come from the closed-loop simulator (book drive gains designed for ID_TEST_MOTOR, 2 s at 10 kHz,
the excitation of tuning.identify.excitation) with 1 % current and 0.5 % voltage noise; every fit here has the
same log shape, so the compiled fit is shared by the whole module.
"""

import json

import numpy as np
import pytest

from pmsmjax.cli import main
from pmsmjax.frames.three_phase import dq_to_abc, inverse_park
from pmsmjax.io.logs import write_csv_atomic
from pmsmjax.recorded.synthetic_logs import (
    ID_LOG_NOISE,
    ID_TEST_MOTOR,
    add_measurement_noise,
    identification_log,
)
from pmsmjax.spec.validation import ParameterError
from tuning.identify import IdentifyOptions, identify
from tuning.identify.excitation import identification_scenario, prbs
from tuning.identify.log import drive_log_from_columns
from tuning.identify.uncertainty import interval_dof

#: Accuracy asked of identification on these logs (relative).
TOLERANCE = {"R": 0.01, "L_d": 0.02, "L_q": 0.02, "psi_f": 0.005, "J": 0.03, "B": 0.10}
COLUMNS = ("time", "u_d", "u_q", "i_d", "i_q", "omega_m", "theta_e")


@pytest.fixture(scope="module")
def clean():
    return identification_log(identification_scenario())


def _fit(columns, hold="stator", **options):
    log = drive_log_from_columns({k: columns[k] for k in COLUMNS}, 4, hold=hold)
    return identify(log, IdentifyOptions(pole_pairs=4, **options)).summary


def _errors(summary):
    return {n: summary["parameters"][n]["value"] / ID_TEST_MOTOR[n] - 1.0 for n in TOLERANCE}


@pytest.mark.slow
def test_accuracy_and_intervals_on_a_noisy_closed_loop_log(clean):
    s = _fit(add_measurement_noise(clean, ID_LOG_NOISE, seed=0))
    err = _errors(s)
    for name, tol in TOLERANCE.items():
        p = s["parameters"][name]
        assert abs(err[name]) < tol, (name, err[name])
        assert p["identifiable"] is True
        assert p["ci95"][0] < p["value"] < p["ci95"][1]
    assert s["identifiability"]["not_identifiable"] == []
    # The residual is the added current noise (1 % of the current RMS, ~0.045 A) plus the voltage
    # noise seen through the machine's low-pass: a little above the current noise, not below.
    sigma = 0.01 * np.sqrt(np.mean(clean["i_d"] ** 2 + clean["i_q"] ** 2))
    for est in (s["noise_estimate"]["i_d_A"], s["residual_rms"]["i_q_A"]):
        assert sigma < est < 1.2 * sigma
    assert len(s["residual_rms_per_window"]["i_d_A"]) == s["solver"]["electrical_windows"]


def test_intervals_cover_the_truth_over_seeds(clean):
    """A small version of benchmarks/bench_identify.py's 50-seed coverage: 8 seeds, 6 parameters."""
    covered = {n: 0 for n in TOLERANCE}
    for seed in range(1, 9):
        s = _fit(add_measurement_noise(clean, ID_LOG_NOISE, seed=seed))
        for n in TOLERANCE:
            lo, hi = s["parameters"][n]["ci95"]
            covered[n] += lo <= ID_TEST_MOTOR[n] <= hi
    # At a true 95 % coverage, 6 or more of 8 happens with probability 0.994 per parameter.
    assert all(c >= 6 for c in covered.values()), covered


def test_interval_dof_matches_the_spread_of_the_variance_estimate():
    """interval_dof against its definition, by Monte Carlo: a linear model with G blocks of unequal
    information, unit noise; the cluster variance estimate's 2 mean^2 / variance is its dof."""
    rng = np.random.default_rng(0)
    G, n, m = 12, 30, 3
    X = rng.standard_normal((G, n, m)) * np.r_[4.0, 1.0, 1.0, np.full(G - 3, 0.4)][:, None, None]
    M = np.einsum("gki,gkj->ij", X, X)
    nu = interval_dof(M, np.einsum("gki,gkj->gij", X, X))
    Xf = X.reshape(-1, m)
    e = rng.standard_normal((20000, G * n))
    resid = e - (e @ Xf) @ np.linalg.solve(M, Xf.T)  # least-squares residuals
    scores = np.einsum("rgk,gki->rgi", resid.reshape(-1, G, n), X)  # (draws, G, m)
    lin = scores @ np.linalg.inv(M)  # l_j^T s_g for every j
    V = np.sum(lin**2, axis=1)  # (draws, m) cluster variance estimates
    empirical = 2.0 * V.mean(0) ** 2 / V.var(0)
    assert np.all(nu < G - 1.5)  # unequal blocks: fewer than G - 1
    np.testing.assert_allclose(nu, empirical, rtol=0.06)
    # Equal blocks: exactly G - 1.
    B = np.broadcast_to(np.eye(m), (G, m, m))
    np.testing.assert_allclose(interval_dof(B.sum(0), B), G - 1.0, rtol=1e-12)


def test_d_current_zero_reports_L_d_not_identifiable():
    log = add_measurement_noise(
        identification_log(identification_scenario(), id_zero=True), ID_LOG_NOISE, seed=0
    )
    assert np.max(np.abs(log["i_d"])) < 0.5  # i_d = 0 control: nothing but noise and small transients
    s = _fit(log)
    ld = s["parameters"]["L_d"]
    assert ld["identifiable"] is False and ld["ci95"] == [None, None]
    assert s["identifiability"]["not_identifiable"] == ["L_d"]
    assert "id_ref" in s["identifiability"]["advice"]["L_d"]
    assert any(d["parameters"] == ["L_d"] for d in s["identifiability"]["weak_directions"])
    err = _errors(s)
    for name in ("R", "L_q", "psi_f", "J", "B"):
        assert abs(err[name]) < TOLERANCE[name] and s["parameters"][name]["identifiable"], name


def test_log_of_a_rotor_frame_hold_simulator_fits_as_well_as_our_own(clean):
    own = _fit(add_measurement_noise(clean, ID_LOG_NOISE, seed=0))
    other = add_measurement_noise(
        identification_log(identification_scenario(), hold="rotor"), ID_LOG_NOISE, seed=0
    )
    s = _fit(other, hold="rotor")
    for name, tol in TOLERANCE.items():
        assert abs(_errors(s)[name]) < tol, name
    for sig in ("i_d_A", "i_q_A"):
        assert s["residual_rms"][sig] == pytest.approx(own["residual_rms"][sig], rel=0.05)
    # The hold matters: the same log read with the inverter's stator hold fits far worse.
    wrong = _fit(other, hold="stator")
    assert wrong["residual_rms"]["i_q_A"] > 3.0 * s["residual_rms"]["i_q_A"]


def test_rk4_at_the_log_step_matches_an_adaptive_solve():
    """One RK4 step per 100 us interval (the fit's model) against diffrax Dopri8 at rtol 1e-10."""
    import jax
    import jax.numpy as jnp

    from pmsmjax.machines import MachineInput, PMSMdq, PMSMParameters, solve_adaptive
    from tuning.identify import electrical as el
    from tuning.identify.log import DriveLog
    from tuning.identify.parameters import ParameterMap

    with jax.enable_x64(True):
        motor = PMSMParameters(**ID_TEST_MOTOR)
        n, dt, w = 41, 1e-4, 110.0  # 110 rad/s: 1050 r/min, omega_e dt = 0.044
        rng = np.random.default_rng(0)
        u = np.column_stack([rng.uniform(-40, 40, n), rng.uniform(20, 120, n)])
        t = np.arange(n) * dt
        theta = 0.3 + 4 * w * t
        log = DriveLog(t, u, np.zeros((n, 2)), np.full(n, w), theta, np.zeros(n))
        names = ("R", "L_d", "L_q", "psi_f")
        pmap = ParameterMap(names, (True,) * 4, (True,) * 4, jnp.asarray([ID_TEST_MOTOR[k] for k in names]),
                            jnp.ones(4))  # fmt: skip
        data = el.ElectricalData.from_log(log, n - 1, np.ones(2), 4, "stator", 1, False, 0.1)
        fast = np.asarray(el.simulate_windows(pmap, jnp.zeros(4), jnp.zeros((1, 2)), data))[0]
        machine = PMSMdq(motor, mechanics="imposed")
        state = machine.initial_state((0.0, 0.0), w, theta[0])
        ref = []
        for k in range(n - 1):
            u_ab = inverse_park(jnp.asarray(u[k]), state.theta_e)
            state = solve_adaptive(machine, state, MachineInput(u_ab, 0.0, "stator"), dt)
            ref.append(np.asarray(state.currents))
    err = np.max(np.abs(fast - np.asarray(ref)))
    assert np.max(np.abs(ref)) > 1.0  # the currents actually move
    assert err < 1e-5, err  # A; the current noise of a log is ~0.05 A


# --------------------------------------------------------------------------------------------------
# log layouts and bad input (no fitting: these fail or pass before anything is compiled)
# --------------------------------------------------------------------------------------------------
def test_stationary_frames_and_duties_give_the_same_dq_signals(clean):
    th = clean["theta_e"]
    u_dq = np.column_stack([clean["u_d"], clean["u_q"]])
    i_dq = np.column_stack([clean["i_d"], clean["i_q"]])
    u_abc, i_abc = np.asarray(dq_to_abc(u_dq, th)), np.asarray(dq_to_abc(i_dq, th))
    u_ab, i_ab = np.asarray(inverse_park(u_dq, th)), np.asarray(inverse_park(i_dq, th))
    base = {"time": clean["time"], "omega_m": clean["omega_m"], "theta_e": th}
    layouts = [
        {"u_a": u_abc[:, 0], "u_b": u_abc[:, 1], "u_c": u_abc[:, 2],
         "i_alpha": i_ab[:, 0], "i_beta": i_ab[:, 1]},
        {"u_alpha": u_ab[:, 0], "u_beta": u_ab[:, 1],
         "i_a": i_abc[:, 0], "i_b": i_abc[:, 1], "i_c": i_abc[:, 2]},
        {"d_a": 0.5 + u_abc[:, 0] / 311, "d_b": 0.5 + u_abc[:, 1] / 311, "d_c": 0.5 + u_abc[:, 2] / 311,
         "U_dc": np.full(th.size, 311.0), "i_d": clean["i_d"], "i_q": clean["i_q"]},
    ]  # fmt: skip
    for layout in layouts:
        log = drive_log_from_columns({**base, **layout}, 4)
        np.testing.assert_allclose(log.u_dq, u_dq, atol=1e-9)
        np.testing.assert_allclose(log.i_dq, i_dq, atol=1e-12)


def test_speed_or_angle_alone_is_completed_from_the_other(clean):
    cols = {k: clean[k] for k in COLUMNS}
    no_speed = drive_log_from_columns({k: v for k, v in cols.items() if k != "omega_m"}, 4)
    moving = np.abs(clean["omega_m"]) > 5
    rel = np.abs(no_speed.omega_m - clean["omega_m"])[moving] / np.abs(clean["omega_m"][moving])
    assert np.median(rel) < 1e-3 and "derived" in no_speed.notes[0]
    no_angle = drive_log_from_columns({k: v for k, v in cols.items() if k != "theta_e"}, 4)
    assert "integrated" in no_angle.notes[0]


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda c: c.update(i_q=np.where(np.arange(c["time"].size) == 7, np.nan, c["i_q"])), "'i_q' is NaN"),
        (lambda c: c.update(time=np.where(np.arange(c["time"].size) == 9, 0.0, c["time"])), "increasing"),
        (lambda c: c.update(time=np.concatenate([c["time"][:50], c["time"][50:] + 3e-5])), "irregular"),
        (lambda c: c.update(omega_m=c["omega_m"] * 30 / np.pi), "rpm"),
        (lambda c: c.update(omega_m=c["omega_m"] * 4), "electrical speed"),
        (lambda c: c.update(time=c["time"] * 1e3), "time = 'ms'"),
        (lambda c: c.pop("u_q"), "u_q missing"),
        (lambda c: c.update(i_Q=c.pop("i_q")), "incomplete"),
    ],
)  # fmt: skip
def test_bad_logs_are_refused_with_the_reason(clean, edit, message):
    cols = {k: clean[k].copy() for k in COLUMNS}
    edit(cols)
    with pytest.raises(ParameterError, match=message):
        drive_log_from_columns(cols, 4)


def test_irregular_sampling_can_be_resampled_and_a_gap_starts_a_capture(clean):
    cols = {k: clean[k][:2000].copy() for k in COLUMNS}
    late = {**cols, "time": np.concatenate([cols["time"][:500], cols["time"][500:] + 3e-5])}  # one 1.3-step
    with pytest.warns(UserWarning, match="resampled"):
        log = drive_log_from_columns(late, 4, resample=True)
    assert np.allclose(np.diff(log.time), 1e-4) and "resampled" in log.notes[0] and log.captures == 1
    keep = np.ones(2000, bool)
    keep[500:503] = False  # three samples dropped: two captures, nothing interpolated across the gap
    log = drive_log_from_columns({k: v[keep] for k, v in cols.items()}, 4)
    assert log.segments.tolist() == [0, 500, 1997] and "2 captures" in log.notes[0]


@pytest.mark.parametrize("fault", ["rpm_without_angle", "swapped_voltages"])
def test_inconsistent_logs_are_refused_before_fitting(clean, fault):
    cols = {k: clean[k] for k in COLUMNS if k != "theta_e"}
    if fault == "rpm_without_angle":
        cols["omega_m"] = cols["omega_m"] * 30 / np.pi
        match = "rpm"
    else:
        cols["u_d"], cols["u_q"] = cols["u_q"], cols["u_d"]
        match = "mislabelled"
    log = drive_log_from_columns(cols, 4)
    with pytest.raises(ParameterError, match=match):
        identify(log, IdentifyOptions(pole_pairs=4))


def test_options_are_checked():
    with pytest.raises(ParameterError, match="unknown parameter"):
        IdentifyOptions(pole_pairs=4, fixed={"Rs": 1.0})
    with pytest.raises(ParameterError, match="must be > 0"):
        IdentifyOptions(pole_pairs=4, fixed={"J": -1.0})
    with pytest.raises(ParameterError, match="pole_pairs"):
        IdentifyOptions(pole_pairs=0)


def test_cli_with_a_column_map_and_units_writes_params_json(clean, tmp_path):
    log = add_measurement_noise(clean, ID_LOG_NOISE, seed=0)
    renamed = {"t_ms": log["time"] * 1e3, "Ud": log["u_d"], "Uq": log["u_q"], "Id": log["i_d"],
               "Iq": log["i_q"], "rpm": log["omega_m"] * 30 / np.pi, "theta": log["theta_e"]}  # fmt: skip
    write_csv_atomic(tmp_path / "log.csv", renamed)
    (tmp_path / "log.toml").write_text(
        '[columns]\ntime = "t_ms"\nu_d = "Ud"\nu_q = "Uq"\ni_d = "Id"\ni_q = "Iq"\nomega_m = "rpm"\n'
        'theta_e = "theta"\n[units]\ntime = "ms"\nomega_m = "rpm"\n'
    )
    out = tmp_path / "out"
    code = main(["identify", str(tmp_path / "log.csv"), "--out", str(out), "--pole-pairs", "4",
                 "--config", str(tmp_path / "log.toml"), "--no-figures"])  # fmt: skip
    assert code == 0
    s = json.loads((out / "params.json").read_text())
    for name in TOLERANCE:
        p = s["parameters"][name]
        assert set(p) >= {"value", "stderr", "ci95", "identifiable"}
        assert abs(p["value"] / ID_TEST_MOTOR[name] - 1) < TOLERANCE[name]
    assert s["wall_time_s"] > 0
    # A wrong unit is an error (exit code 2), and no params.json is written.
    bad = tmp_path / "bad"
    code = main(["identify", str(tmp_path / "log.csv"), "--out", str(bad), "--pole-pairs", "4",
                 "--config", str(tmp_path / "log.toml"), "--units", "omega_m=rad/s"])  # fmt: skip
    assert code == 2 and not (bad / "params.json").exists()


def test_excitation_scenario_and_prbs():
    bits = prbs(254)
    assert set(np.unique(bits)) == {-1.0, 1.0}
    np.testing.assert_array_equal(bits[:127], bits[127:])  # maximum length: period 2^7 - 1
    assert abs(bits[:127].sum()) == 1  # balanced to one bit
    sc = identification_scenario(duration_s=2.0)
    assert sc.duration_s == 2.0 and float(np.max(np.abs(sc.id_ref.values))) == 3.0
    speeds = np.asarray(sc.speed_ref.values)
    assert speeds.min() < 0 < speeds.max() and np.unique(speeds).size >= 6
    with pytest.raises(ParameterError):
        identification_scenario(speeds_rpm=[100.0])


@pytest.mark.slow
def test_benchmark_smoke_and_the_numpy_residuals_agree_with_jax(clean, tmp_path):
    """benchmarks/bench_identify.py at 3 seeds: its JSON, and its NumPy residuals (an independent
    implementation, the one SciPy fits) against the JAX ones at the same point."""
    import jax
    import jax.numpy as jnp
    from jax.flatten_util import ravel_pytree

    from benchmarks.bench_identify import main as bench_main
    from benchmarks.bench_identify import numpy_residuals
    from tuning.identify.fit import joint_residuals

    r = bench_main(str(tmp_path / "bench.json"), quick=True)
    assert json.loads((tmp_path / "bench.json").read_text())["n_seeds"] == 3
    assert r["scipy"]["max_difference_in_stderr"] < 0.01
    assert set(r["coverage"]) == set(TOLERANCE)
    log = drive_log_from_columns(
        {k: v for k, v in add_measurement_noise(clean, ID_LOG_NOISE, seed=0).items() if k in COLUMNS}, 4
    )
    fit = identify(log, IdentifyOptions(pole_pairs=4)).fit
    ed = {k: np.asarray(getattr(fit.electrical, k)) for k in ("i", "dt", "u", "w_e", "sigma")}
    md = {k: np.asarray(getattr(fit.mechanical, k)) for k in ("i", "dt", "w", "load", "sigma")}
    md["pole_pairs"] = 4
    theta = fit.theta + 0.01  # away from the optimum
    with jax.enable_x64(True):
        ref = ravel_pytree(joint_residuals(jnp.asarray(theta), (fit.pmap, fit.electrical, fit.mechanical)))[0]
    np.testing.assert_allclose(
        numpy_residuals(theta, fit.pmap, ed, md), np.asarray(ref), rtol=1e-9, atol=1e-9
    )


@pytest.mark.slow
def test_dead_time_voltage_is_recovered(clean):
    """A log whose logged (commanded) voltage exceeds the applied one by a dead-time drop of 2 V per phase,
    ``u_logged = u_applied + V_dt park(clarke(sign(i_abc)))``: with ``dead_time=True`` the fit finds V_dt
    and the motor; without it R absorbs the drop and is off by more than the asked 1 %."""
    from pmsmjax.frames.three_phase import abc_to_alpha_beta, park

    th = clean["theta_e"]
    sgn = np.sign(np.asarray(dq_to_abc(np.column_stack([clean["i_d"], clean["i_q"]]), th)))
    drop = 2.0 * np.asarray(park(abc_to_alpha_beta(sgn), th))
    log = add_measurement_noise(
        {**clean, "u_d": clean["u_d"] + drop[:, 0], "u_q": clean["u_q"] + drop[:, 1]}, ID_LOG_NOISE, seed=0
    )
    s = _fit(log, dead_time=True)
    v = s["extra_parameters"]["V_dt"]
    assert v["identifiable"] and abs(v["value"] - 2.0) < 0.1, v
    for name, tol in TOLERANCE.items():
        assert abs(_errors(s)[name]) < tol, name
    assert abs(_errors(_fit(log))["R"]) > 0.01
