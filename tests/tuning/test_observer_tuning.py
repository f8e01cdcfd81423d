"""Gradient tuning of the chapter 5 observers: the tuning objective's gradient w.r.t.
every tunable observer parameter; the sensored warm-up, the angle-error metric against NumPy, resume and
the ``pmsmjax tune --estimator`` outputs.

Independent reference: central finite differences of the same loss in float64 (tests/conftest.py), at
the design-rule point; and finiteness of the gradient over 1000 random draws of the parameters within a
factor 2 of the design rule (draws the observer's own stability check refuses are redrawn: outside its
linearised stability region the observer is not a candidate). One compiled, vmapped value-and-gradient
per observer evaluates the design point, the 2n finite-difference points and the 1000 draws in one call.

The warm-up wrapper is pmsmjax/estimators/sensored_warmup.py.
"""

import importlib
import json

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers.gradient_check import CentralDifferences, assert_gradient_close

import pmsmjax
from pmsmjax.cli import main
from pmsmjax.estimators import OBSERVERS
from pmsmjax.spec.validation import ParameterError
from tuning.autotune import TuneConfig, tune
from tuning.autotune.job import run_tune_job
from tuning.autotune.objectives import ObjectiveWeights, scenario_metrics, smoothed_batch_cost, start_at_speed
from tuning.autotune.observers import (
    TUNABLE_OBSERVERS,
    WARMUP_S,
    make_observer_batch,
    observer_drive,
    observer_tuning,
)
from tuning.parameters import (
    LogParameterisation,
    apply_gains,
    get_leaf,
    read_gains_toml,
    set_leaves,
    write_gains_toml,
)

N_DRAWS = 1000
H = 1e-5  # log-space step of the central differences (the design point is theta = 0)
# one step and one speed (1200 periods: warm-up 20 ms, step at 40 ms, load step at 66-84 ms)
BATCH = make_observer_batch(1, 3, duration_s=(0.12, 0.12), speed_rpm=(300.0, 1500.0), kinds=("step",))


def test_every_observer_has_a_table_entry():
    from pmsmjax.estimators.registry import HYBRID_OBSERVERS, INJECTION_OBSERVERS

    assert set(TUNABLE_OBSERVERS) == set(OBSERVERS) | set(INJECTION_OBSERVERS) | set(HYBRID_OBSERVERS)


def _stable_draws(drive, param, rng, n):
    """``n`` log-factor draws in [log 1/2, log 2] whose observer passes ``check_period``."""
    draws, refused = [], 0
    while len(draws) < n:
        theta = rng.uniform(np.log(0.5), np.log(2.0), param.p0.shape)
        try:
            param.apply(drive, jnp.asarray(theta)).estimator.check_period(drive.Ts)
        except ParameterError:
            refused += 1
            continue
        draws.append(theta)
    return np.stack(draws), refused


@pytest.mark.slow
@pytest.mark.parametrize("name", list(OBSERVERS))
def test_gradient_matches_central_differences_and_is_finite_over_draws(name):
    tuning = observer_tuning(name)
    drive = observer_drive(name, n_substeps=1)
    weights = ObjectiveWeights(**tuning.weights)
    param = LogParameterisation(drive, tuning.names, (0.05, 20.0))
    n = len(param.names)

    def loss(theta):
        return smoothed_batch_cost(param.apply(drive, theta), BATCH, weights)[0]

    draws, refused = _stable_draws(drive, param, np.random.default_rng(0), N_DRAWS)
    stencil = CentralDifferences.around(np.zeros(n), rel_step=H, labels=param.names)
    points = np.concatenate([np.zeros((1, n)), stencil.points(), draws])
    values, grads = jax.jit(jax.vmap(jax.value_and_grad(loss)))(jnp.asarray(points))
    values, grads = np.asarray(values), np.asarray(grads)

    g = grads[0]
    fd = stencil.quotients(values[1 : 1 + stencil.size])
    assert_gradient_close(g, fd, names=stencil.names, x=stencil.x, rtol=1e-4, value=values[0])
    # every parameter moves the loss (a zero gradient would make the check above vacuous)
    assert np.all(np.abs(g) > 1e-6 * values[0]), (name, g)
    draw_grads = grads[1 + stencil.size :]
    assert np.all(np.isfinite(values[1 + stencil.size :])) and np.all(np.isfinite(draw_grads)), name
    assert refused < N_DRAWS, (name, refused)


def test_vector_leaf_elements_are_named_and_set():
    """EKF Q and R diagonals are tuned element by element (``estimator.observer.q[2]``)."""
    drive = observer_drive("ekf", n_substeps=1)
    q = np.asarray(get_leaf(drive, "estimator.observer.q"))
    assert float(get_leaf(drive, "estimator.observer.q[2]")) == q[2]
    new = set_leaves(drive, ["estimator.observer.q[2]", "estimator.observer.q[0]"], [1.0, 2.0])
    np.testing.assert_array_equal(np.asarray(new.estimator.observer.q), [2.0, q[1], 1.0, q[3]])


@pytest.fixture(scope="module")
def mras_run():
    """One observer scenario of the MRAS drive (behind the sensored warm-up), started at speed."""
    drive = observer_drive("mras", n_substeps=1)
    batch = make_observer_batch(1, 5, duration_s=(0.12, 0.12), kinds=("step",))
    scenario = jax.tree.map(lambda a: a[0], batch.scenarios)
    start = start_at_speed(drive, batch.initial_speed_m[0], batch.initial_theta_e[0])
    return drive, batch, pmsmjax.simulate(drive, scenario, initial_state=start)


@pytest.mark.slow
def test_warmup_hands_over_at_its_time_and_the_angle_metric_matches_numpy(mras_run):
    drive, batch, tr = mras_run
    t = np.asarray(tr.t)
    err = np.asarray(tr.theta_e_est) - np.asarray(tr.theta_e)
    warm = t < WARMUP_S - 1e-9
    # on the sensor until the hand-over: the estimate is the plant's angle to rounding (wrapped the same)
    assert np.max(np.abs(np.angle(np.exp(1j * err[warm])))) < 1e-9
    assert np.max(np.abs(np.angle(np.exp(1j * err[~warm])))) > 1e-6  # then the observer's own estimate
    assert abs(float(tr.omega_m[0]) - float(batch.initial_speed_m[0])) < 1e-9  # started at speed
    m = scenario_metrics(tr, batch.duration_s[0], batch.load_time_s[0], 15.0, 300.0, observe_from_s=WARMUP_S)
    keep = (t >= WARMUP_S - 1e-12) & (t < float(batch.duration_s[0]) - 1e-12)
    wrapped = (err[keep] + np.pi) % (2 * np.pi) - np.pi
    assert float(m["angle_error_rms_rad"]) == pytest.approx(np.sqrt(np.mean(wrapped**2)), rel=1e-10)
    chord = 2 * np.sin(err[keep] / 2)
    assert float(m["angle_chord_rms_rad"]) == pytest.approx(np.sqrt(np.mean(chord**2)), rel=1e-10)
    assert 0 < float(m["angle_error_rms_rad"]) < np.radians(10)  # locked


@pytest.mark.slow
def test_observer_tuning_resumes_exactly_and_the_command_writes_its_outputs(tmp_path):
    """``tune`` on an observer: an interrupted run resumes to the same history and gains; ``pmsmjax tune
    --estimator`` writes gains.toml (observer paths), result.json with angle errors, figures."""
    tuning = observer_tuning("mras")
    drive = observer_drive("mras", n_substeps=1)
    batch = make_observer_batch(2, 7, duration_s=(0.12, 0.12), kinds=("step",))
    weights = ObjectiveWeights(**tuning.weights)
    cfg = TuneConfig(
        names=tuning.names, method="adam", learning_rate=0.1, max_iterations=5, checkpoint_every=1
    )
    reference = tune(drive, batch, weights, cfg, progress=False)
    path = tmp_path / "checkpoint.npz"

    def interrupt(iteration, cost):
        if iteration == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        tune(drive, batch, weights, cfg, checkpoint_path=path, progress=False, callback=interrupt)
    resumed = tune(drive, batch, weights, cfg, checkpoint_path=path, progress=False)
    assert resumed.resumed_from == 2
    assert resumed.history == reference.history and resumed.gains == reference.gains

    out = tmp_path / "tune"
    args = ["tune", "--estimator", "mras", "--out", str(out), "--train", "2", "--heldout", "2"]
    args += ["--iterations", "2", "--duration-s", "0.12", "0.12", "--eval-substeps", "2", "--no-progress"]
    assert main(args) == 0
    data = json.loads((out / "result.json").read_text())
    assert data["estimator"] == "mras" and data["stability"] == "stable"
    for part in ("train", "heldout"):
        for when in ("before", "after"):
            assert np.isfinite(data[part][when]["angle_error_rms_rad"])
    gains = read_gains_toml(out / "gains.toml")
    assert set(gains) == set(tuning.names)
    for name in ("cost.png", "responses.png", "checkpoint.npz"):
        assert (out / name).stat().st_size > 0
    # the tuned gains apply to the I/f-start drive too (same path estimator.observer.*)
    from pmsmjax import presets

    started = apply_gains(presets.sensorless_drive("mras", startup=True), gains)
    assert float(started.estimator.observer.kp) == pytest.approx(gains["estimator.observer.kp"])


def test_estimator_needs_the_foc_control(tmp_path):
    with pytest.raises(
        ParameterError, match="--estimator ekf tunes an observer on the three-phase FOC drive"
    ):
        run_tune_job(tmp_path, estimator="ekf", control="smc", n_train=1, n_heldout=1)


@pytest.mark.slow
def test_tuned_observer_gains_apply_in_demo(tmp_path, monkeypatch):
    """``pmsmjax demo --estimator smo --gains`` takes a gains.toml of ``tune --estimator smo`` (observer
    paths, speed_bandwidth included) on the I/f-start drive: the drive it simulates is the design-rule
    drive with exactly the file's values in place, and the run follows the design-rule run to the bit
    through the I/f ramp (where the observer's output is not used) and departs from it once the observer
    takes over."""
    names = observer_tuning("smo").names
    values = [1.1 * float(get_leaf(observer_drive("smo", n_substeps=1), n)) for n in names]
    gains = tmp_path / "gains.toml"
    write_gains_toml(gains, names, values)
    engine = importlib.import_module("pmsmjax.simulate")  # the module (pmsmjax.simulate is the function)
    simulated, simulate = [], engine.simulate
    monkeypatch.setattr(engine, "simulate", lambda d, *a, **k: (simulated.append(d), simulate(d, *a, **k))[1])
    args = ["demo", "--estimator", "smo", "--duration-s", "0.05", "--load-time-s", "0.04", "--no-figures"]
    runs = {}
    for label, extra in (("design", []), ("tuned", ["--gains", str(gains)])):
        out = tmp_path / label
        assert main([*args, *extra, "--out", str(out)]) == 0
        trace = np.genfromtxt(out / "trace.csv", delimiter=",", names=True)
        runs[label] = (simulated[-1], trace, json.loads((out / "summary.json").read_text()))
    (design, a, summary_a), (tuned, b, summary_b) = runs["design"], runs["tuned"]
    assert summary_b["drive"]["gains"] == str(gains) and summary_a["drive"]["gains"] is None
    # the simulated drive: the file's values, and nothing else changed
    assert [float(get_leaf(tuned, n)) for n in names] == values
    assert [float(get_leaf(design, n)) for n in names] == pytest.approx([v / 1.1 for v in values], rel=1e-14)
    assert bool(eqx.tree_equal(tuned, set_leaves(design, names, [jnp.asarray(v) for v in values])))
    # the runs: equal before the observer starts to take over (t = handover speed / ramp acceleration)
    handover_s = float(tuned.estimator.handover_speed / tuned.estimator.accel)
    before = a["time"] < handover_s - 1e-9
    assert 0.1 < before.mean() < 0.9  # the hand-over lies inside the run
    np.testing.assert_array_equal(a["theta_e_est"][before], b["theta_e_est"][before])
    np.testing.assert_array_equal(a["omega_m"][before], b["omega_m"][before])
    assert np.max(np.abs(a["theta_e_est"] - b["theta_e_est"])[~before]) > 1e-3  # rad: the gains act
    assert summary_b["metrics"]["itae_rad_s"] != pytest.approx(summary_a["metrics"]["itae_rad_s"], rel=1e-3)


# ------------------------------------------------------------- on a drive file with a flux map
# saturated-ipm (pmsmjax/presets/motors/saturated_ipm.toml): the tuned observer is the map-aware one that
# demo runs there (pmsmjax/assemble.py map_aware): flux-observer reads the map itself, a back-EMF observer
# sits inside the map's angle correction, one level down (estimator.observer.observer.<gain>).
MAP_OBSERVERS = {"flux-observer": "MapFluxObserver", "smo-pll": "MapAngleCorrected"}


@pytest.fixture(scope="module")
def saturated_ipm():
    from pmsmjax.io.drive_files import drive_spec

    return drive_spec("saturated-ipm")


@pytest.mark.parametrize("name", list(MAP_OBSERVERS))
def test_the_map_aware_observer_is_the_one_tuned_on_a_flux_map_file(saturated_ipm, name):
    from tuning.autotune.observers import tuned_names

    drive = observer_drive(name, spec=saturated_ipm, n_substeps=1)
    inner = drive.estimator.observer
    assert type(inner).__name__ == MAP_OBSERVERS[name]
    names = tuned_names(name, drive)
    head = "estimator.observer." if name == "flux-observer" else "estimator.observer.observer."
    assert names == tuple(head + n.split(".", 2)[2] for n in observer_tuning(name).names)
    assert all(isinstance(get_leaf(drive, n), jnp.ndarray) for n in names)
    # reading the file's map: the flux observer's own relation, the correction's interpolant
    assert inner.flux_map is not None
    # observer_model="constant": the file's constants, the book paths
    constant = observer_drive(name, spec=saturated_ipm, n_substeps=1, observer_model="constant")
    assert tuned_names(name, constant) == observer_tuning(name).names
    assert getattr(constant.estimator.observer, "flux_map", None) is None


@pytest.mark.slow
@pytest.mark.parametrize("name", list(MAP_OBSERVERS))
def test_gradient_through_the_map_matches_central_differences(saturated_ipm, name):
    """The loss of the map-aware observer on one saturated-ipm scenario (warm-up, speed step, load step)
    differentiated through the map's bicubic interpolant: every tuned gain's derivative finite, non-zero
    and equal to central differences of the same loss."""
    from tuning.autotune import drive_scaling
    from tuning.autotune.drive_batches import drive_batches
    from tuning.autotune.observers import tuned_names

    batches = drive_batches(saturated_ipm, name)
    drive = observer_drive(name, spec=saturated_ipm, n_substeps=1, warmup_s=batches.warmup_s)
    batch = batches.make(1, 3, duration_s=(0.12, 0.12), kinds=("step",))
    weights = drive_scaling.scaled_weights(ObjectiveWeights(**observer_tuning(name).weights), saturated_ipm)
    param = LogParameterisation(drive, tuned_names(name, drive), (0.05, 20.0))
    n = len(param.names)

    def loss(theta):
        return smoothed_batch_cost(param.apply(drive, theta), batch, weights)[0]

    stencil = CentralDifferences.around(np.zeros(n), rel_step=H, labels=param.names)
    points = np.concatenate([np.zeros((1, n)), stencil.points()])
    values, grads = jax.jit(jax.vmap(jax.value_and_grad(loss)))(jnp.asarray(points))
    values, g = np.asarray(values), np.asarray(grads)[0]
    assert np.all(np.isfinite(values)) and np.all(np.isfinite(g))
    assert np.all(np.abs(g) > 1e-6 * values[0]), (name, g)
    fd = stencil.quotients(values[1:])
    assert_gradient_close(g, fd, names=stencil.names, x=stencil.x, rtol=1e-4, value=values[0])


@pytest.mark.slow
def test_tune_on_the_flux_map_file_writes_gains_demo_reads(tmp_path, saturated_ipm, monkeypatch):
    """``tune --motor saturated-ipm --estimator smo-pll`` tunes the map-aware observer's gains (paths under
    the map's angle correction) and ``demo --motor saturated-ipm --estimator smo-pll --gains`` simulates
    the map-aware I/f-start drive with exactly those values in place."""
    out = tmp_path / "tune"
    argv = ["tune", "--motor", "saturated-ipm", "--estimator", "smo-pll", "--out", str(out)]
    argv += ["--train", "1", "--heldout", "1", "--iterations", "2", "--duration-s", "0.12", "0.12"]
    assert main([*argv, "--eval-substeps", "1", "--no-progress"]) == 0
    data = json.loads((out / "result.json").read_text())
    gains = read_gains_toml(out / "gains.toml")
    names = observer_tuning("smo-pll").names
    assert set(gains) == {n.replace("estimator.observer.", "estimator.observer.observer.") for n in names}
    assert gains == pytest.approx(data["gains"]["after"], rel=1e-12)
    assert all(np.isfinite(c) for c in data["cost_history"]) and data["stability"] == "stable"

    engine = importlib.import_module("pmsmjax.simulate")
    simulated, simulate = [], engine.simulate
    monkeypatch.setattr(engine, "simulate", lambda d, *a, **k: (simulated.append(d), simulate(d, *a, **k))[1])
    # the tune's own file, and the same names 1.1x off (one step of 2 may keep the design rule: the
    # values must be seen to arrive)
    moved = tmp_path / "moved.toml"
    write_gains_toml(moved, list(gains), [1.1 * v for v in gains.values()])
    for path, expected in ((out / "gains.toml", gains), (moved, {n: 1.1 * v for n, v in gains.items()})):
        demo = ["demo", "--motor", "saturated-ipm", "--estimator", "smo-pll", "--gains", str(path)]
        demo += ["--duration-s", "0.1", "--load-time-s", "0.08", "--no-figures", "--out", str(tmp_path / "d")]
        assert main(demo) == 0
        drive = simulated[-1]
        assert type(drive.estimator.observer).__name__ == "MapAngleCorrected"  # under the I/f start
        assert {n: float(get_leaf(drive, n)) for n in gains} == pytest.approx(expected, rel=1e-6)


def test_an_overflowing_gradient_still_moves_adam():
    """A lost-lock batch's gradient (1e27 measured: smo-pll on saturated-ipm's observer batches) squares
    past float32's range: Adam's second moment turns infinite, for good, and its step is zero. The tuner
    scales such a gradient down, direction kept, and leaves every other one untouched to the bit."""
    import optax

    from tuning.autotune.tuner import finite_square

    normal = jnp.asarray([-0.19, 0.14, 3e15], jnp.float32)
    assert np.array_equal(np.asarray(finite_square(normal)), np.asarray(normal))
    huge = jnp.asarray([-4.5e27, 4.5e27, -1.3e27], jnp.float32)
    scaled = np.asarray(finite_square(huge))
    assert np.all(np.isfinite(scaled**2)) and np.allclose(scaled / scaled[0], np.asarray(huge / huge[0]))
    adam = optax.adam(0.2)
    theta = jnp.zeros(3, jnp.float32)
    frozen, _ = adam.update(huge, adam.init(theta), theta)
    moved, _ = adam.update(finite_square(huge), adam.init(theta), theta)
    assert np.all(np.asarray(frozen) == 0.0)  # what the tuner did before
    np.testing.assert_allclose(np.asarray(moved), [0.2, -0.2, 0.2], rtol=1e-5)
