"""Gradient auto-tuning of drive gains over a batch of scenarios.

The cost ([`tuning.autotune.objectives`][tuning.autotune.objectives]) of the whole batch is differentiated
through every closed-loop simulation with reverse-mode AD, and ``theta = log(p/p0)`` moves from the
design-rule gains by ``method="adam"`` (a cosine-decayed step) or ``method="bfgs"``
([`tuning.autotune.quasi_newton`][tuning.autotune.quasi_newton]: step-capped BFGS on the cost with its penalty
kinks rounded, one gradient per iteration; far fewer iterations on a handful of gains). Costs reported and
compared are always the exact ones. The best iterate is kept; tuning stops at ``max_iterations``, when the
cost has not improved by ``min_rel_improvement`` for ``patience`` iterations, or when the time budget is
spent.

Host work out of the device's way: the cost-and-gradient function is compiled ahead of time (a compiled
call returns once dispatched, where ``eqx.filter_jit`` waits for its results), and each iteration
dispatches the next evaluation before its bookkeeping (progress bar, checkpoint, callback), so that
bookkeeping runs while the device computes; the host waits only where it needs the cost. The
evaluations, and so the tuning path, are the same as when they were made one after another.

Checkpoints (``checkpoint_path``, NumPy ``.npz``, written atomically every ``checkpoint_every``
iterations and at the end) hold theta, the optimiser state, the best iterate and the history, plus a
fingerprint of the problem; running the same tuning again resumes from it and, because every step is
deterministic, ends exactly where an uninterrupted run would.
"""

import dataclasses
import hashlib
import time
from collections.abc import Callable
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
from tqdm.auto import tqdm

from pmsmjax.drive import Drive
from pmsmjax.io.logs import atomic_write
from pmsmjax.spec.validation import ParameterError
from tuning.autotune.objectives import ObjectiveWeights, batch_cost, smoothed_batch_cost
from tuning.autotune.quasi_newton import bfgs_init, bfgs_tell
from tuning.autotune.scenario_batches import ScenarioBatch
from tuning.parameters import LogParameterisation


@dataclasses.dataclass(frozen=True)
class TuneConfig:
    """Settings of a tuning run.

    - `names`: gains to tune (dotted names or the aliases ``speed``, ``current``).
    - `method`: ``"adam"`` or ``"bfgs"`` (see the module docstring).
    - `learning_rate`: Adam step in log-space (0.05 = about 5 % change per step at most).
    - `max_step`: BFGS's largest log-space change of any gain per trial (0.5: a factor 1.65).
    - `overshoot_smoothing_pct`, `current_smoothing_a`: BFGS only: the widths over which the kinks of
      the overshoot and current penalties are rounded
      ([`tuning.autotune.objectives.smoothed_penalty`][tuning.autotune.objectives.smoothed_penalty]) in the
      cost it follows; 0 = exact. The current's rounding lies inside the limit, so it is narrow (10 mA): a
      tuned drive accelerates on its current limit, and a zone of 0.1 A kept the servo-400w and
      outer-rotor-24v drives 40 mA off it, cutting their held-out ITAE by 5-8 % instead of 47-49 %
      (benchmarks/user_drive_tuning.py).
    - `max_iterations`, `patience`, `min_rel_improvement`: stopping rules.
    - `bounds`: factors on the starting gains, ``(lower <= 1, upper >= 1)``.
    - `time_budget_s`: stop after this much wall time (compile included), None for no limit.
    - `checkpoint_every`: iterations between checkpoints.
    """

    names: tuple[str, ...] = ("speed", "current")
    method: str = "adam"
    learning_rate: float = 0.08
    max_step: float = 0.5
    overshoot_smoothing_pct: float = 1.0
    current_smoothing_a: float = 0.01
    max_iterations: int = 120
    patience: int = 25
    min_rel_improvement: float = 1e-4
    bounds: tuple[float, float] = (0.05, 20.0)
    time_budget_s: float | None = None
    checkpoint_every: int = 5

    def __post_init__(self):
        if self.method not in ("adam", "bfgs"):
            raise ParameterError(f"method must be 'adam' or 'bfgs', got {self.method!r}.")
        if not (self.learning_rate > 0 and np.isfinite(self.learning_rate)):
            raise ParameterError(f"learning_rate must be > 0, got {self.learning_rate}.")
        if not (self.max_step > 0 and np.isfinite(self.max_step)):
            raise ParameterError(f"max_step must be a positive log-factor, got {self.max_step}.")
        for f in ("overshoot_smoothing_pct", "current_smoothing_a"):
            v = getattr(self, f)
            if not (np.isfinite(v) and v >= 0):
                raise ParameterError(f"{f} must be >= 0 (0: exact penalties), got {v}.")
        for f in ("max_iterations", "patience", "checkpoint_every"):
            v = getattr(self, f)
            if not isinstance(v, int) or v < 1:
                raise ParameterError(f"{f} must be an int >= 1, got {v!r}.")
        if self.time_budget_s is not None and not self.time_budget_s > 0:
            raise ParameterError(f"time_budget_s must be > 0 or None, got {self.time_budget_s}.")


@dataclasses.dataclass
class TuneResult:
    """Outcome of [`tune`][tuning.autotune.tuner.tune].

    `drive`: the drive with the best gains; `gains`: name -> value; `history`: cost per iteration;
    `best_cost`, `initial_cost`; `iterations` done in total; `stopped`: why it stopped;
    `wall_time_s` and `compile_time_s` of this call (the ahead-of-time compile of the cost and gradient);
    `resumed_from`: the iteration a checkpoint was resumed from (0 when starting fresh);
    `waiting_time_s`: of the wall time after compiling, the part the host spent waiting for the device's
    results (the rest is host work not hidden behind a computation: optimiser steps, bookkeeping).
    """

    drive: Drive
    gains: dict
    history: list
    best_cost: float
    initial_cost: float
    iterations: int
    stopped: str
    wall_time_s: float
    compile_time_s: float
    resumed_from: int
    waiting_time_s: float = 0.0


class TuneInterrupted(KeyboardInterrupt):
    """Ctrl-C during [`tune`][tuning.autotune.tuner.tune]; the message says at which iteration and where the
    checkpoint is. `iteration`: the iterations the saved checkpoint holds."""

    def __init__(self, message: str, iteration: int):
        super().__init__(message)
        self.iteration = iteration


def _fingerprint(param: LogParameterisation, batch: ScenarioBatch, weights, config: TuneConfig) -> str:
    """A hash of everything that determines the tuning path (to refuse resuming a different problem)."""
    h = hashlib.sha256()
    h.update(repr((param.names, weights, dataclasses.replace(config, time_budget_s=None))).encode())
    for leaf in jax.tree.leaves((param.p0, batch)):
        h.update(np.asarray(leaf).tobytes())
    return h.hexdigest()[:16]


def _nan_report(drive, batch, weights) -> str:
    _, costs, _ = batch_cost(drive, batch, weights)
    bad = np.flatnonzero(~np.isfinite(np.asarray(costs)))
    if bad.size == 0:
        return "the batch cost is not finite although every scenario's cost is"
    k = int(bad[0])
    return (
        f"scenario {k} ({batch.kind[k]}) has a non-finite cost"
        + (f" (and {bad.size - 1} more)" if bad.size > 1 else "")
        + ": the gains left the stable region; lower learning_rate or tighten bounds."
    )


def finite_square(grad):
    """``grad`` scaled down, direction kept, where its largest entry's square would overflow (beyond
    ``sqrt(max float) / 1e3``, 1.8e16 in float32); unchanged otherwise (bit for bit). Why: Adam keeps the
    running mean of ``grad**2``, and one infinite entry stays infinite through its decay, so that
    coordinate's step is zero from then on and tuning stops without a word. Such gradients come from a
    batch with scenarios that lose the angle (an observer on a saturated machine: 1e27 measured), whose
    loss is chaotic in the gains; the scaled one gives Adam a sign to follow."""
    big = jnp.max(jnp.abs(grad))
    limit = jnp.sqrt(jnp.finfo(grad.dtype).max) * 1e-3
    return jnp.where(big > limit, grad * (limit / jnp.where(big > limit, big, 1.0)), grad)


def _evaluate(theta, drive, batch, follow: ObjectiveWeights, param: LogParameterisation):
    """``(exact cost, followed cost, gradient of the followed cost)`` of the batch at ``theta``."""
    f = lambda th: smoothed_batch_cost(param.apply(drive, th), batch, follow)
    (followed, exact), grad = jax.value_and_grad(f, has_aux=True)(theta)
    return exact, followed, grad


_value_and_grad = eqx.filter_jit(_evaluate)


def compile_value_and_grad(theta, drive, batch, follow: ObjectiveWeights, param: LogParameterisation):
    """`_evaluate` compiled ahead of time for ``theta``'s shape; returns ``evaluate(theta)``.

    The drive, batch and parameterisation are split into arrays and the rest once, here: a call then
    only hands the arrays to the compiled program and returns without waiting for it (measured on the
    1,024-scenario batch: 0.7 ms of host time per call through ``eqx.filter_jit``'s argument handling).
    """
    arrays, rest = eqx.partition((drive, batch, param), eqx.is_array)

    def f(th, arrays):
        d, b, p = eqx.combine(arrays, rest)
        return _evaluate(th, d, b, follow, p)

    compiled = jax.jit(f).lower(theta, arrays).compile()
    return lambda th: compiled(th, arrays)


def tune(
    drive: Drive,
    batch: ScenarioBatch,
    weights: ObjectiveWeights | None = None,
    config: TuneConfig | None = None,
    *,
    checkpoint_path: str | Path | None = None,
    progress: bool = True,
    callback: Callable[[int, float], None] | None = None,
) -> TuneResult:
    """Tune ``config.names`` of ``drive`` to minimise the batch cost; see the module docstring.

    `weights` and `config` default to [`ObjectiveWeights`][tuning.autotune.objectives.ObjectiveWeights] and
    [`TuneConfig`][tuning.autotune.tuner.TuneConfig] defaults. `callback(iteration, cost)` is called after
    every iteration (e.g. to log or to interrupt).
    """
    weights = ObjectiveWeights() if weights is None else weights
    config = TuneConfig() if config is None else config
    if batch.size < 1:
        raise ParameterError("the scenario batch is empty: tune needs at least one scenario.")
    start = time.perf_counter()
    param = LogParameterisation(drive, config.names, config.bounds)
    schedule = optax.cosine_decay_schedule(config.learning_rate, config.max_iterations, alpha=0.1)
    optimiser = optax.adam(schedule)
    bfgs = config.method == "bfgs"
    # The cost the optimiser follows: BFGS's has the penalty kinks rounded; history and best use the exact.
    follow = weights
    if bfgs:
        follow = dataclasses.replace(
            weights,
            overshoot_smoothing_pct=config.overshoot_smoothing_pct,
            current_smoothing_a=config.current_smoothing_a,
        )

    # The drive and batch are arguments, not constants folded into the program (measured: 0.31 s per
    # BFGS iteration against 0.35 s on the 64-scenario problem).
    @eqx.filter_jit
    def update(theta, grad, opt_state):
        updates, opt_state = optimiser.update(finite_square(grad), opt_state, theta)
        return param.project(optax.apply_updates(theta, updates)), opt_state

    def next_point(theta, followed, grad, opt_state):
        if not bfgs:
            return update(theta, grad, opt_state)
        bounds = dict(lower=float(param.log_lower), upper=float(param.log_upper), max_step=config.max_step)
        x, opt_state = bfgs_tell(opt_state, theta, followed, grad, **bounds)
        return jnp.asarray(x, theta.dtype), opt_state

    theta = param.initial_theta()
    opt_state = bfgs_init(theta.size, config.max_step) if bfgs else optimiser.init(theta)
    best_theta, best_cost, history, it0 = theta, np.inf, [], 0
    fingerprint = _fingerprint(param, batch, weights, config)
    path = Path(checkpoint_path) if checkpoint_path is not None else None
    if path is not None and path.is_file():
        theta, opt_state, best_theta, best_cost, history, it0 = _load_checkpoint(path, fingerprint, opt_state)

    t_compile = time.perf_counter()
    value_and_grad = compile_value_and_grad(theta, drive, batch, follow, param)
    compile_s = time.perf_counter() - t_compile
    waiting = [0.0]

    def wait_for(evaluation):
        """``(cost as a float, followed cost, gradient)`` once the device has them."""
        t_wait = time.perf_counter()
        cost, followed, grad = evaluation
        cost = float(cost)
        waiting[0] += time.perf_counter() - t_wait
        return cost, followed, grad

    t_loop = time.perf_counter()
    cost, followed, grad = wait_for(value_and_grad(theta))
    stopped = "max_iterations"
    since_best = _iterations_since_best(history, config.min_rel_improvement)  # 0 unless resumed
    bar = tqdm(
        total=config.max_iterations, initial=it0, disable=not progress, desc="tune", unit="it", leave=False
    )
    it = it0
    # The last consistent resume point (every field from the same iteration): what Ctrl-C saves.
    snapshot = (theta, opt_state, best_theta, best_cost, list(history), it)
    try:
        while it < config.max_iterations:
            # BFGS backs off from a trial that destabilises the drive; its start, and Adam, cannot.
            if not np.isfinite(cost) and not (bfgs and it > 0):
                report = _nan_report(param.apply(drive, theta), batch, weights)
                raise ParameterError(f"tuning cost is NaN at iteration {it}: {report}")
            history.append(cost)
            if cost < best_cost * (1.0 - config.min_rel_improvement):
                best_theta, best_cost, since_best = theta, cost, 0
            else:
                since_best += 1
            theta, opt_state = next_point(theta, followed, grad, opt_state)
            it += 1
            snapshot = (theta, opt_state, best_theta, best_cost, list(history), it)
            stop = None
            if since_best >= config.patience:
                stop = "no improvement"
            elif config.time_budget_s is not None and time.perf_counter() - start > config.time_budget_s:
                stop = "time budget"
            # The next evaluation starts now and runs while the host does this iteration's bookkeeping.
            evaluation = value_and_grad(theta) if stop is None and it < config.max_iterations else None
            bar.update(1)
            bar.set_postfix(cost=f"{cost:.5g}", best=f"{best_cost:.5g}")
            if path is not None and (it % config.checkpoint_every == 0):
                _save_checkpoint(path, fingerprint, theta, opt_state, best_theta, best_cost, history, it)
            if callback is not None:  # after the checkpoint: an interrupt here loses no finished step
                callback(it, cost)
            if stop is not None:
                stopped = stop
                break
            if evaluation is not None:
                cost, followed, grad = wait_for(evaluation)
    except KeyboardInterrupt:
        bar.close()
        where = ""
        if path is not None:
            _save_checkpoint(path, fingerprint, *snapshot)
            where = f"; the checkpoint {path} holds it: rerun the same command to resume"
        raise TuneInterrupted(
            f"at iteration {snapshot[-1]} of {config.max_iterations}{where}", snapshot[-1]
        ) from None
    finally:
        bar.close()
    loop_end = time.perf_counter()
    if path is not None:
        _save_checkpoint(path, fingerprint, theta, opt_state, best_theta, best_cost, history, it)
    values = np.asarray(param.values(best_theta))
    return TuneResult(
        drive=param.apply(drive, best_theta),
        gains={n: float(v) for n, v in zip(param.names, values, strict=True)},
        history=[float(c) for c in history],
        best_cost=float(best_cost),
        initial_cost=float(history[0]) if history else float("nan"),
        iterations=it,
        stopped=stopped,
        wall_time_s=time.perf_counter() - start,
        compile_time_s=compile_s,
        resumed_from=it0,
        waiting_time_s=min(waiting[0], loop_end - t_loop),
    )


def _iterations_since_best(history, min_rel_improvement: float) -> int:
    """The early-stopping counter after ``history``, replayed with the loop's own rule (so a resumed run
    stops exactly where an uninterrupted one would; the counter itself is not checkpointed)."""
    best, since = np.inf, 0
    for cost in history:
        if cost < best * (1.0 - min_rel_improvement):
            best, since = cost, 0
        else:
            since += 1
    return since


def _save_checkpoint(path, fingerprint, theta, opt_state, best_theta, best_cost, history, iteration):
    leaves = jax.tree.leaves(opt_state)
    arrays = {f"opt_{i}": np.asarray(x) for i, x in enumerate(leaves)}
    arrays.update(
        theta=np.asarray(theta),
        best_theta=np.asarray(best_theta),
        best_cost=np.asarray(best_cost),
        history=np.asarray(history, dtype=np.float64),
        iteration=np.asarray(iteration),
        fingerprint=np.asarray(fingerprint),
    )
    atomic_write(path, lambda f: np.savez(f, **arrays))


def _load_checkpoint(path, fingerprint, opt_state_template):
    try:
        data = np.load(path)
    except Exception as err:  # a truncated or foreign file
        raise ParameterError(
            f"checkpoint {path} cannot be read ({type(err).__name__}): rerun with --fresh (pmsmjax tune) or "
            "delete it to start over."
        ) from err
    with data:
        if "fingerprint" not in data.files or str(data["fingerprint"]) != fingerprint:
            raise ParameterError(
                f"checkpoint {path} belongs to a different tuning problem (gains, scenarios, weights or "
                "settings changed): to start fresh, rerun with --fresh (pmsmjax tune; it replaces the "
                "checkpoint) or delete the file; to keep it, write to another output folder (--out)."
            )
        treedef = jax.tree.structure(opt_state_template)
        n = treedef.num_leaves
        # NumPy as saved: exact dtypes (BFGS keeps float64 state; Adam's float32 state stays float32).
        opt_state = jax.tree.unflatten(treedef, [np.asarray(data[f"opt_{i}"]) for i in range(n)])
        return (
            jnp.asarray(data["theta"]),
            opt_state,
            jnp.asarray(data["best_theta"]),
            float(data["best_cost"]),
            [float(c) for c in data["history"]],
            int(data["iteration"]),
        )
