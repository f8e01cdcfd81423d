"""Gradient auto-tuning: scenario batches, objectives against independent computations, the tuner's
improvement, determinism, checkpoint/resume, and its input errors. Small sizes (the reference run of 64
scenarios is `pmsmjax tune` itself; its figures are in the README)."""

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import pmsmjax
from pmsmjax import ParameterError, presets
from pmsmjax.cli import main
from pmsmjax.units import rad_s_to_rpm
from tuning.autotune import TuneConfig, tune
from tuning.autotune.objectives import (
    ObjectiveWeights,
    aggregate,
    batch_cost,
    scenario_metrics,
    smoothed_penalty,
)
from tuning.autotune.quasi_newton import bfgs_init, bfgs_tell
from tuning.autotune.scenario_batches import make_batch
from tuning.parameters import LogParameterisation, apply_gains, read_gains_toml, write_gains_toml

SMALL = dict(duration_s=(0.08, 0.1))


@pytest.fixture(scope="module")
def drive():
    return presets.book_drive(n_substeps=1)


@pytest.fixture(scope="module")
def batch():
    return make_batch(4, 3, **SMALL)


def test_batches_are_reproducible_and_within_ranges():
    a, b, c = make_batch(32, 7), make_batch(32, 7), make_batch(32, 8)
    assert all(np.array_equal(x, y) for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True))
    assert not np.array_equal(a.scenarios.speed_ref.values, c.scenarios.speed_ref.values)
    speed_rpm = rad_s_to_rpm(np.asarray(a.scenarios.speed_ref.values[:, -1]))
    assert np.all((np.abs(speed_rpm) >= 200 - 1e-6) & (np.abs(speed_rpm) <= 1500 + 1e-6))
    assert (speed_rpm > 0).any() and (speed_rpm < 0).any()  # both directions
    load = np.asarray(a.scenarios.load_torque.values[:, -1])
    assert np.all(np.sign(load) * np.sign(speed_rpm) >= 0) and np.all(np.abs(load) <= 10)  # opposes motion
    d, t_load = np.asarray(a.duration_s), np.asarray(a.load_time_s)
    assert np.all((d >= 0.3 - 1e-9) & (d <= 0.5 + 1e-9)) and np.all((t_load > 0.5 * d) & (t_load < 0.71 * d))


def test_reversal_and_ramp_kinds():
    b = make_batch(12, 1, kinds=("reversal", "ramp"), **SMALL)
    assert set(b.kind) == {"reversal", "ramp"}
    for k, kind in enumerate(b.kind):
        v = np.asarray(b.scenarios.speed_ref.values[k])
        if kind == "reversal":
            assert v[0] == pytest.approx(-v[-1])


def test_scenario_metrics_match_an_independent_numpy_computation(drive, batch):
    """ITAE over the scenario's own duration, overshoot in the pre-load window, peak and excess current."""
    k = 1
    scenario = jax.tree.map(lambda a: a[k], batch.scenarios)
    # A deliberately aggressive speed loop so the step overshoots and the comparison is not with zero.
    fast = apply_gains(
        drive,
        {"controller.speed.kp": 0.3, "controller.speed.ki": 300.0, "controller.speed.active_damping": 0.01},
    )
    tr = pmsmjax.simulate(fast, scenario)
    m = scenario_metrics(tr, batch.duration_s[k], batch.load_time_s[k], 15.0, 311 / 3**0.5)
    t, w, ref = (np.asarray(x) for x in (tr.t, tr.omega_m, tr.speed_ref))
    dur, t_load = float(batch.duration_s[k]), float(batch.load_time_s[k])
    keep = t < dur - 1e-12
    assert float(m["itae"]) == pytest.approx(np.sum(t[keep] * np.abs(ref - w)[keep]) * 1e-4, rel=1e-10)
    pre = t < t_load - 1e-12
    final = ref[pre][-1]
    expected_overshoot = 100 * max(np.max(np.sign(final) * (w[pre] - final)), 0) / abs(final)
    assert expected_overshoot > 1.0
    assert float(m["overshoot_pct"]) == pytest.approx(expected_overshoot, rel=1e-10)
    peak = np.max(np.abs(np.asarray(tr.i_abc))[keep])
    assert float(m["peak_current_a"]) == pytest.approx(peak, rel=1e-12)
    assert float(m["current_excess_a"]) == pytest.approx(max(peak - 15.0, 0.0), abs=1e-12)


def test_cvar_is_the_mean_of_the_worst_share():
    costs = jnp.array([3.0, 1.0, 7.0, 2.0, 9.0, 4.0, 5.0, 6.0, 8.0, 0.5])
    w = ObjectiveWeights(aggregate="cvar", cvar_alpha=0.8)
    assert float(aggregate(costs, w)) == pytest.approx(np.mean([9.0, 8.0]))
    assert float(aggregate(costs, ObjectiveWeights())) == pytest.approx(float(np.mean(costs)))


def test_log_parameterisation(drive):
    p = LogParameterisation(drive, ["speed", "controller.current.kp_q"], bounds=(0.5, 2.0))
    assert p.names[:3] == ("controller.speed.kp", "controller.speed.ki", "controller.speed.active_damping")
    same = p.apply(drive, p.initial_theta())
    assert all(
        np.array_equal(x, y) for x, y in zip(jax.tree.leaves(same), jax.tree.leaves(drive), strict=True)
    )
    theta = p.project(jnp.array([5.0, -5.0, 0.1, 0.0]))
    np.testing.assert_allclose(p.values(theta) / p.p0, [2.0, 0.5, np.exp(0.1), 1.0], rtol=1e-12)
    assert float(p.apply(drive, theta).controller.speed.kp) == pytest.approx(2.0 * float(p.p0[0]))


@pytest.mark.parametrize(
    "names, bounds, message",
    [
        (["controller.speed.kpp"], (0.1, 10.0), "unknown gain name"),
        ([], (0.1, 10.0), "no gains selected"),
        (["speed"], (0.0, 10.0), "bounds"),
        (["speed"], (2.0, 10.0), "bounds"),
        (["speed", "controller.speed.kp"], (0.1, 10.0), "repeat"),
    ],
)
def test_bad_tuning_selection(drive, names, bounds, message):
    with pytest.raises(ParameterError, match=message):
        LogParameterisation(drive, names, bounds)


def test_non_positive_start_is_refused(drive):
    zero = apply_gains(drive, {"controller.speed.active_damping": 0.0})
    with pytest.raises(ParameterError, match="not positive"):
        LogParameterisation(zero, ["speed"])


def test_gains_file_round_trip(drive, tmp_path):
    gains = {"controller.speed.kp": 0.25, "controller.current.ki_q": 812.5}
    write_gains_toml(tmp_path / "g.toml", list(gains), list(gains.values()), header="test")
    assert read_gains_toml(tmp_path / "g.toml") == gains
    d = apply_gains(drive, tmp_path / "g.toml")
    assert float(d.controller.speed.kp) == 0.25 and float(d.controller.current.ki_q) == 812.5
    with pytest.raises(ParameterError, match="unknown gain"):
        apply_gains(drive, {"controller.speed.kx": 1.0})


@pytest.mark.slow
def test_tuning_lowers_the_cost_and_is_deterministic(drive, batch):
    cfg = TuneConfig(max_iterations=8, learning_rate=0.1)
    a = tune(drive, batch, config=cfg, progress=False)
    b = tune(drive, batch, config=cfg, progress=False)
    assert a.best_cost < 0.9 * a.initial_cost
    assert a.history == b.history and a.gains == b.gains
    # The reported best cost is the cost of the returned drive.
    assert float(batch_cost(a.drive, batch, ObjectiveWeights())[0]) == pytest.approx(a.best_cost, rel=1e-9)


def _interrupt_and_resume(drive, batch, cfg, at: int, path):
    """Tune with checkpoints at ``path``, interrupted after iteration ``at``; return the resumed run."""

    def interrupt(iteration, cost):
        if iteration == at:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        tune(drive, batch, config=cfg, checkpoint_path=path, progress=False, callback=interrupt)
    resumed = tune(drive, batch, config=cfg, checkpoint_path=path, progress=False)
    assert resumed.resumed_from == at
    return resumed


def test_interrupted_tuning_resumes_to_the_same_result(drive, batch, tmp_path):
    cfg = TuneConfig(max_iterations=8, learning_rate=0.1, checkpoint_every=1)
    reference = tune(drive, batch, config=cfg, progress=False)

    path = tmp_path / "checkpoint.npz"
    resumed = _interrupt_and_resume(drive, batch, cfg, 4, path)
    assert resumed.history == reference.history
    assert resumed.gains == reference.gains
    # A checkpoint of another problem is refused, not silently reused.
    with pytest.raises(ParameterError, match="different tuning problem"):
        tune(drive, batch, config=TuneConfig(max_iterations=9), checkpoint_path=path, progress=False)


def test_smoothed_penalty_rounds_only_the_kink():
    x = np.linspace(-3.0, 5.0, 801)
    w = 2.0
    expected = np.where(x <= 0, 0.0, np.where(x < w, x**2 / (2 * w), x - w / 2))  # the Huber form
    got = np.asarray(smoothed_penalty(jnp.asarray(x), w))
    np.testing.assert_allclose(got, expected, atol=1e-12)
    assert np.all(got <= np.maximum(x, 0.0) + 1e-12)  # never above the exact penalty
    slope = jax.vmap(jax.grad(lambda v: smoothed_penalty(v, w)))(
        jnp.asarray([-1e-9, 1e-9, w - 1e-9, w + 1e-9])
    )
    np.testing.assert_allclose(np.asarray(slope), [0.0, 0.0, 1.0, 1.0], atol=1e-6)  # continuous slope
    np.testing.assert_array_equal(np.asarray(smoothed_penalty(jnp.asarray(x), 0.0)), np.maximum(x, 0.0))


def _ask_tell(f, x0, lower, upper, evaluations, max_step=0.5):
    grad = jax.grad(f)
    state, x = bfgs_init(x0.size, max_step), np.asarray(x0, np.float64)
    for _ in range(evaluations):
        x, state = bfgs_tell(state, x, float(f(x)), np.asarray(grad(x)), lower=lower, upper=upper,
                             max_step=max_step)  # fmt: skip
    return state


def test_bfgs_finds_the_rosenbrock_minimum_and_stops_at_an_active_bound():
    rosenbrock = lambda v: (1.0 - v[0]) ** 2 + 100.0 * (v[1] - v[0] ** 2) ** 2
    with jax.enable_x64(True):
        state = _ask_tell(rosenbrock, np.array([-1.2, 1.0]), -3.0, 3.0, 150)
        np.testing.assert_allclose(state.x, [1.0, 1.0], atol=1e-4)  # the known minimum
        # A bowl centred outside the box [-1, 1]^2 at (2, 0.3): the box minimum is (1, 0.3).
        bowl = lambda v: (v[0] - 2.0) ** 2 + 3.0 * (v[1] - 0.3) ** 2
        state = _ask_tell(bowl, np.array([0.0, 0.0]), -1.0, 1.0, 30)
        np.testing.assert_allclose(state.x, [1.0, 0.3], atol=1e-6)
        # Every step is capped: the first trial from the start moves no coordinate by more than max_step.
        x1, _ = bfgs_tell(
            bfgs_init(2), np.zeros(2), 1.0, np.array([-50.0, 1.0]), lower=-3, upper=3, max_step=0.5
        )
        assert np.max(np.abs(x1)) == pytest.approx(0.5)


@pytest.mark.slow
def test_bfgs_tuning_lowers_the_exact_cost_and_resumes_exactly(drive, batch, tmp_path):
    # Early stopping ends this run: interrupted between its last improvement and its stop, a resumed run
    # must stop at the same place, so the stopping counter has to survive the interruption.
    cfg = TuneConfig(
        method="bfgs", max_iterations=12, patience=3, min_rel_improvement=0.02, checkpoint_every=1
    )
    reference = tune(drive, batch, config=cfg, progress=False)
    assert reference.best_cost < 0.9 * reference.initial_cost
    # Reported costs are exact (not the rounded cost BFGS follows): the best is the returned drive's.
    assert float(batch_cost(reference.drive, batch, ObjectiveWeights())[0]) == pytest.approx(
        reference.best_cost, rel=1e-9
    )

    assert reference.stopped == "no improvement"
    best_so_far = np.minimum.accumulate(reference.history)
    improved = [k for k in range(1, len(best_so_far)) if best_so_far[k] < (1 - 0.02) * best_so_far[k - 1]]
    at = improved[-1] + 2  # iterations are 1-based: one iteration after the last improvement
    assert at < reference.iterations  # the interruption falls inside the patience window
    resumed = _interrupt_and_resume(drive, batch, cfg, at, tmp_path / "checkpoint.npz")
    assert resumed.history == reference.history and resumed.gains == reference.gains
    assert resumed.stopped == reference.stopped and resumed.iterations == reference.iterations


def test_early_stopping(drive, batch):
    cfg = TuneConfig(max_iterations=50, patience=3, min_rel_improvement=0.99)
    r = tune(drive, batch, config=cfg, progress=False)
    assert r.stopped == "no improvement" and r.iterations == 4


def test_nan_cost_names_the_scenario(drive, batch):
    """Even absurd gains stay finite (the voltage and current limits bound the loop), so the NaN is put
    into scenario 2's load (bypassing the Profile checks, as corrupted data could)."""
    import equinox as eqx

    values = batch.scenarios.load_torque.values.at[2, -1].set(jnp.nan)
    corrupted = eqx.tree_at(lambda b: b.scenarios.load_torque.values, batch, values)
    with pytest.raises(ParameterError, match="scenario 2"):
        tune(drive, corrupted, config=TuneConfig(max_iterations=2), progress=False)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(learning_rate=0.0), "learning_rate"),
        (dict(max_iterations=0), "max_iterations"),
        (dict(time_budget_s=-1.0), "time_budget_s"),
        (dict(method="sgd"), "method"),
        (dict(max_step=0.0), "max_step"),
        (dict(current_smoothing_a=-0.1), "current_smoothing_a"),
    ],
)
def test_bad_config(kwargs, message):
    with pytest.raises(ParameterError, match=message):
        TuneConfig(**kwargs)


def test_bad_batch_and_weights():
    with pytest.raises(ParameterError, match="n >= 1"):
        make_batch(0, 0)
    with pytest.raises(ParameterError, match="kinds"):
        make_batch(2, 0, kinds=("spin",))
    with pytest.raises(ParameterError, match="itae"):
        ObjectiveWeights(itae=-1.0)


@pytest.mark.slow
def test_tune_command_writes_its_outputs(tmp_path):
    out = tmp_path / "tune"
    args = ["tune", "--out", str(out), "--train", "2", "--heldout", "2", "--iterations", "3"]
    assert main([*args, "--duration-s", "0.05", "0.06", "--no-progress"]) == 0
    data = json.loads((out / "result.json").read_text())
    for part in ("train", "heldout"):
        for when in ("before", "after"):
            assert np.isfinite(data[part][when]["itae"])
            assert len(data[part][when]["per_scenario"]) == 2
    for key in ("wall_time_s", "compile_time_s", "iterations", "cost_history"):
        assert key in data
    gains = read_gains_toml(out / "gains.toml")
    assert gains == pytest.approx(data["gains"]["after"], rel=1e-12)
    for name in ("cost.png", "responses.png", "checkpoint.npz"):
        assert (out / name).stat().st_size > 0


@pytest.mark.slow
def test_settling_time_matches_the_first_order_design(drive):
    """The design-rule speed loop is beta/(s + beta): 2 % settling at ln(50)/beta (78.2 ms at 50 rad/s)."""
    b = make_batch(3, 5, duration_s=(0.25, 0.3))
    from tuning.autotune.objectives import batch_metrics

    settling = np.asarray(batch_metrics(drive, b)["settling_time_s"])
    beta = presets.BOOK_SPEED_BANDWIDTH
    # Only steps small enough to stay off the current limit follow the linear design.
    small = np.abs(np.asarray(b.scenarios.speed_ref.values[:, -1])) * float(drive.controller.speed.kp) < 14
    assert small.any()
    np.testing.assert_allclose(settling[small], np.log(50) / beta, rtol=0.03)


@pytest.mark.slow
def test_plant_spread_runs_each_scenario_on_its_own_plant(drive):
    """Scenario k of a spread batch equals the nominal scenario run on a plant with J scaled by its factor."""
    from tuning.autotune.objectives import batch_metrics

    spread = make_batch(3, 4, plant_spread={"J": 0.5}, **SMALL)
    nominal = make_batch(3, 4, **SMALL)
    scale = np.asarray(spread.plant_scale["J"])
    assert np.all(np.abs(scale - 1) <= 0.5) and np.ptp(scale) > 0
    m = batch_metrics(drive, spread)
    for k in range(3):
        import equinox as eqx

        heavy = eqx.tree_at(lambda d: d.machine.motor.J, drive, drive.machine.motor.J * scale[k])
        one = jax.tree.map(lambda a, k=k: a[k : k + 1], nominal)
        assert float(m["itae"][k]) == pytest.approx(float(batch_metrics(heavy, one)["itae"][0]), rel=1e-10)
    with pytest.raises(ParameterError, match="plant_spread"):
        make_batch(2, 0, plant_spread={"J": 1.5})


def test_tune_config_file(tmp_path):
    from tuning.autotune.job import read_tune_toml

    path = tmp_path / "tune.toml"
    path.write_text(
        "[weights]\nitae = 2.0\naggregate = 'cvar'\n[tune]\nlearning_rate = 0.05\n"
        "[job]\nn_train = 8\nduration_s = [0.1, 0.2]\nplant_spread = {J = 0.3}\n"
    )
    kw = read_tune_toml(path)
    assert kw["weights"].itae == 2.0 and kw["weights"].aggregate == "cvar"
    assert kw["config"].learning_rate == 0.05 and kw["n_train"] == 8 and kw["duration_s"] == (0.1, 0.2)
    assert kw["plant_spread"] == {"J": 0.3}
    path.write_text("[weights]\nitea = 1.0\n")
    with pytest.raises(ParameterError, match="itea"):
        read_tune_toml(path)
