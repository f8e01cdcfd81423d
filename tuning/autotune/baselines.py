"""Derivative-free baselines for gain tuning, on exactly the objective and batch the gradient tuner uses.

The gradient tuner ([`tuning.autotune.tuner.tune`][tuning.autotune.tuner.tune]) is only worth its reverse-mode
AD if it beats what a plain search reaches with the same cost function. These baselines search the same
log-space ``theta = log(p / p0)``
([`tuning.parameters.LogParameterisation`][tuning.parameters.LogParameterisation], the same bounds, theta = 0
at the design-rule gains) and call one jit-compiled batch cost ``theta -> float``:

- [`design_rule_cost`][tuning.autotune.baselines.design_rule_cost]: the cost of the untouched design-rule
  gains (the starting point of all);
- [`nelder_mead`][tuning.autotune.baselines.nelder_mead]: `scipy.optimize.minimize` with
  ``method="Nelder-Mead"``, its simplex clipped to the bounds;
- [`cma_es`][tuning.autotune.baselines.cma_es]: CMA-ES from the optional package ``cma``
  ([`cma_available`][tuning.autotune.baselines.cma_available] says whether it is installed; without it
  [`cma_es`][tuning.autotune.baselines.cma_es] raises `ImportError` naming the fix).

Each returns a [`BaselineResult`][tuning.autotune.baselines.BaselineResult] whose ``trace`` is the best cost
so far against the number of evaluations and the wall time (compile excluded; ``compile_time_s`` reports it
separately), so a benchmark can put both searches and the gradient tuner on one cost-vs-time plot.
"""

import dataclasses
import importlib.util
import time
from collections.abc import Callable, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import scipy.optimize

from pmsmjax.drive import Drive
from pmsmjax.spec.validation import ParameterError
from tuning.autotune.objectives import ObjectiveWeights, batch_cost
from tuning.autotune.scenario_batches import ScenarioBatch
from tuning.parameters import LogParameterisation

__all__ = ["BaselineResult", "design_rule_cost", "nelder_mead", "cma_es", "cma_available", "make_cost"]

#: Cost given to the search for gains whose simulation is not finite (unstable loops): large enough to
#: be rejected by every comparison, finite so simplex and covariance arithmetic stay defined.
NON_FINITE_COST = 1e6


@dataclasses.dataclass
class BaselineResult:
    """Outcome of a search: derivative-free, or L-BFGS-B on JAX gradients.

    - `method`: ``"nelder-mead"``, ``"cma-es"`` or ``"l-bfgs-b"``.
    - `drive`: the drive with the best gains; `gains`: name -> value; `theta`: ``(n,)`` best log-factors.
    - `best_cost`, `initial_cost` (the design-rule gains, theta = x0).
    - `evaluations`: cost evaluations spent; `stopped`: why the search ended.
    - `wall_time_s`: wall time of the search, compile excluded; `compile_time_s`: first cost call minus
      a steady one (about 0 when an earlier search in the process compiled the same shapes: the
      compiled cost is shared).
    - `trace`: ``[(evaluations, wall_s, best_cost), ...]``, one row per improvement of the best cost and
      one for the last evaluation; ``best_cost`` never increases along it.
    """

    method: str
    drive: Drive
    gains: dict
    theta: np.ndarray
    best_cost: float
    initial_cost: float
    evaluations: int
    stopped: str
    wall_time_s: float
    compile_time_s: float
    trace: list

    @property
    def time_to_best_s(self) -> float:
        """Wall time (s, compile excluded) at which the search first reached its final best cost."""
        return next(w for _, w, c in self.trace if c <= self.best_cost)


def cma_available() -> bool:
    """Whether the optional package ``cma`` (for [`cma_es`][tuning.autotune.baselines.cma_es]) is
    importable."""
    return importlib.util.find_spec("cma") is not None


@eqx.filter_jit
def _theta_cost(theta, drive, batch, weights, param):
    return batch_cost(param.apply(drive, param.project(theta)), batch, weights)[0]


@eqx.filter_jit
def _theta_cost_and_grad(theta, drive, batch, weights, param):
    return jax.value_and_grad(lambda th: batch_cost(param.apply(drive, th), batch, weights)[0])(theta)


@eqx.filter_jit
def _drive_cost(drive, batch, weights):
    return batch_cost(drive, batch, weights)[0]


def make_cost(
    drive: Drive, batch: ScenarioBatch, weights: ObjectiveWeights, param: LogParameterisation
) -> Callable[[np.ndarray], float]:
    """One jit-compiled batch cost ``theta (n,) -> float``, theta projected onto the bounds first.

    The drive and the batch are arguments of the compiled function (not constants folded into it), so
    one compilation serves every search on problems of the same shapes.
    """
    dtype = param.p0.dtype

    def f(theta) -> float:
        return float(_theta_cost(jnp.asarray(theta, dtype), drive, batch, weights, param))

    return f


def design_rule_cost(drive: Drive, batch: ScenarioBatch, weights: ObjectiveWeights | None = None) -> float:
    """Batch cost of ``drive`` as it is (the design-rule gains for a preset drive)."""
    weights = ObjectiveWeights() if weights is None else weights
    if batch.size < 1:
        raise ParameterError("the scenario batch is empty: the cost needs at least one scenario.")
    return float(_drive_cost(drive, batch, weights))


class _BudgetSpent(Exception):
    """Raised inside the objective to end a search exactly at its evaluation budget."""


class _Recorder:
    """Counts evaluations, keeps the best point, records the trace and enforces the budget."""

    def __init__(self, f, param, max_evaluations: int, callback):
        self.f, self.param, self.max_evaluations, self.callback = f, param, max_evaluations, callback
        self.evaluations, self.best_cost, self.best_theta, self.trace = 0, np.inf, None, []
        self.initial_cost = np.nan
        self.start = time.perf_counter()

    def __call__(self, theta) -> float:
        if self.evaluations >= self.max_evaluations:
            raise _BudgetSpent
        theta = np.clip(np.asarray(theta, dtype=np.float64), self.param.log_lower, self.param.log_upper)
        cost = self.f(theta)
        self.evaluations += 1
        if self.evaluations == 1:
            self.initial_cost = cost
        if not np.isfinite(cost):
            cost = NON_FINITE_COST
        wall = time.perf_counter() - self.start
        if cost < self.best_cost:
            self.best_cost, self.best_theta = cost, theta.copy()
            self.trace.append((self.evaluations, wall, cost))
        if self.callback is not None:
            self.callback(self.evaluations, cost, self.best_cost)
        return cost

    def result(self, method: str, drive: Drive, compile_time_s: float, stopped: str) -> BaselineResult:
        wall = time.perf_counter() - self.start
        if self.trace and self.trace[-1][0] != self.evaluations:
            self.trace.append((self.evaluations, wall, self.best_cost))
        values = np.asarray(self.param.values(jnp.asarray(self.best_theta, self.param.p0.dtype)))
        return BaselineResult(
            method=method,
            drive=self.param.apply(drive, jnp.asarray(self.best_theta, self.param.p0.dtype)),
            gains={n: float(v) for n, v in zip(self.param.names, values, strict=True)},
            theta=self.best_theta,
            best_cost=float(self.best_cost),
            initial_cost=float(self.initial_cost),
            evaluations=self.evaluations,
            stopped=stopped,
            wall_time_s=wall,
            compile_time_s=compile_time_s,
            trace=[(int(e), float(w), float(c)) for e, w, c in self.trace],
        )


def _setup(drive, batch, weights, names, max_evaluations, bounds, x0):
    """Parameterisation, start point and the compiled cost (compiled here, timed separately)."""
    if batch.size < 1:
        raise ParameterError("the scenario batch is empty: a search needs at least one scenario.")
    if not isinstance(max_evaluations, int) or max_evaluations < 1:
        raise ParameterError(f"max_evaluations must be an int >= 1, got {max_evaluations!r}.")
    param = LogParameterisation(drive, names, bounds)
    n = len(param.names)
    x0 = np.zeros(n) if x0 is None else np.asarray(x0, dtype=np.float64)
    if x0.shape != (n,) or not np.all(np.isfinite(x0)):
        raise ParameterError(f"x0 must be {n} finite log-factors (one per gain {param.names}), got {x0}.")
    x0 = np.clip(x0, param.log_lower, param.log_upper)
    f = make_cost(drive, batch, weights, param)
    t0 = time.perf_counter()
    f(x0)
    first = time.perf_counter() - t0
    t0 = time.perf_counter()
    f(x0)
    steady = time.perf_counter() - t0
    return param, x0, f, max(first - steady, 0.0)


def nelder_mead(
    drive: Drive,
    batch: ScenarioBatch,
    weights: ObjectiveWeights | None = None,
    names: Sequence[str] = ("speed", "current"),
    max_evaluations: int = 2000,
    bounds: tuple[float, float] = (0.05, 20.0),
    *,
    x0=None,
    initial_step: float = 0.5,
    adaptive: bool = False,
    xatol: float = 1e-8,
    fatol: float = 1e-10,
    seed: int = 0,
    callback: Callable[[int, float, float], None] | None = None,
) -> BaselineResult:
    """Nelder-Mead on the batch cost in log-space, from ``x0`` (default 0: the design-rule gains).

    **Arguments:**

    - `drive`, `batch`, `weights`: the problem, exactly as for
      [`tuning.autotune.tuner.tune`][tuning.autotune.tuner.tune].
    - `names`: gains to tune (dotted names or the aliases ``speed``, ``current``).
    - `max_evaluations`: cost evaluations allowed (the search stops exactly there).
    - `bounds`: factors on the starting gains, ``(lower <= 1, upper >= 1)``; the simplex is clipped to them.
    - `x0`: ``(n,)`` starting log-factors (default zeros).
    - `initial_step`: edge of the initial simplex in log-space (0.5: each gain x1.65 in turn). scipy's
      default for a zero start (0.00025) would start the search from a point-sized simplex.
    - `adaptive`: scipy's dimension-adapted coefficients.
    - `xatol`, `fatol`: scipy's convergence tolerances; small by default so the budget ends the search.
    - `seed`: unused by the (deterministic) simplex method; accepted for the same signature as
      [`cma_es`][tuning.autotune.baselines.cma_es].
    - `callback(evaluations, cost, best_cost)`: called after every evaluation.
    """
    del seed
    weights = ObjectiveWeights() if weights is None else weights
    if not (np.isfinite(initial_step) and initial_step > 0):
        raise ParameterError(f"initial_step must be a positive log-factor, got {initial_step}.")
    param, x0, f, compile_s = _setup(drive, batch, weights, names, max_evaluations, bounds, x0)
    n = x0.size
    # Step each coordinate towards its farther bound, no farther than that bound (a vertex clipped onto
    # its neighbour would make the simplex degenerate).
    up, down = param.log_upper - x0, x0 - param.log_lower
    steps = np.where(up >= down, np.minimum(initial_step, up), -np.minimum(initial_step, down))
    simplex = np.vstack([x0, x0 + np.diag(steps)])
    recorder = _Recorder(f, param, max_evaluations, callback)
    stopped = "converged"
    try:
        res = scipy.optimize.minimize(
            recorder,
            x0,
            method="Nelder-Mead",
            bounds=[(param.log_lower, param.log_upper)] * n,
            options={
                "initial_simplex": simplex,
                "maxfev": max_evaluations + n + 1,  # the recorder stops it first
                "maxiter": 100 * max_evaluations,
                "xatol": xatol,
                "fatol": fatol,
                "adaptive": adaptive,
            },
        )
        if not res.success:
            stopped = str(res.message)
    except _BudgetSpent:
        stopped = "max_evaluations"
    return recorder.result("nelder-mead", drive, compile_s, stopped)


def cma_es(
    drive: Drive,
    batch: ScenarioBatch,
    weights: ObjectiveWeights | None = None,
    names: Sequence[str] = ("speed", "current"),
    max_evaluations: int = 2000,
    bounds: tuple[float, float] = (0.05, 20.0),
    *,
    x0=None,
    sigma0: float = 0.5,
    population_size: int | None = None,
    seed: int = 0,
    callback: Callable[[int, float, float], None] | None = None,
) -> BaselineResult:
    """CMA-ES (package ``cma``, optional) on the batch cost in log-space, from ``x0`` (default 0).

    Same problem and arguments as [`nelder_mead`][tuning.autotune.baselines.nelder_mead]; `sigma0` is the
    initial step size in log-space, `population_size` the number of candidates per generation (``cma``'s
    default ``4 + 3 ln n`` when None), `seed` the sampling seed (runs are reproducible). Candidates are
    evaluated one at a time on the same compiled cost as the other searches. Raises `ImportError` when ``cma``
    is missing.
    """
    if not cma_available():
        raise ImportError(
            "cma_es needs the optional package 'cma', which is not installed: `pip install cma` "
            "(or use nelder_mead, which needs only scipy)."
        )
    import cma

    weights = ObjectiveWeights() if weights is None else weights
    if not (np.isfinite(sigma0) and sigma0 > 0):
        raise ParameterError(f"sigma0 must be a positive log-factor, got {sigma0}.")
    param, x0, f, compile_s = _setup(drive, batch, weights, names, max_evaluations, bounds, x0)
    options = {
        "bounds": [param.log_lower, param.log_upper],
        "maxfevals": max_evaluations,
        "seed": seed + 1,  # cma treats seed 0 as "draw a random seed"
        "verbose": -9,
        "tolfun": 1e-12,
        "tolx": 1e-12,
    }
    if population_size is not None:
        options["popsize"] = int(population_size)
    es = cma.CMAEvolutionStrategy(x0, sigma0, options)
    recorder = _Recorder(f, param, max_evaluations, callback)
    recorder(x0)  # the start point is an evaluation too: the trace begins at the design-rule cost
    stopped = "max_evaluations"
    try:
        while not es.stop():
            candidates = es.ask()
            es.tell(candidates, [recorder(x) for x in candidates])
        stop = es.stop()
        stopped = ", ".join(stop) if stop else stopped
    except _BudgetSpent:
        pass
    return recorder.result("cma-es", drive, compile_s, stopped)


def lbfgs_b(
    drive: Drive,
    batch: ScenarioBatch,
    weights: ObjectiveWeights | None = None,
    names: Sequence[str] = ("speed", "current"),
    max_evaluations: int = 300,
    bounds: tuple[float, float] = (0.05, 20.0),
    *,
    x0=None,
    callback: Callable[[int, float, float], None] | None = None,
) -> BaselineResult:
    """Gradient-based search: scipy's L-BFGS-B on the batch cost in log-space, JAX reverse-mode gradients.

    Box bounds are handled by L-BFGS-B's active set, which suits optima on the bounds (where a tanh
    reparameterisation would flatten the gradient). Each evaluation is one value-and-gradient of the
    batch (about 4-5 forward batches). Same arguments as
    [`nelder_mead`][tuning.autotune.baselines.nelder_mead].
    """
    weights = ObjectiveWeights() if weights is None else weights
    if batch.size < 1:
        raise ParameterError("the scenario batch is empty: a search needs at least one scenario.")
    if not isinstance(max_evaluations, int) or max_evaluations < 1:
        raise ParameterError(f"max_evaluations must be an int >= 1, got {max_evaluations!r}.")
    param = LogParameterisation(drive, names, bounds)
    n = len(param.names)
    x0 = np.zeros(n) if x0 is None else np.clip(np.asarray(x0, float), param.log_lower, param.log_upper)
    dtype = param.p0.dtype
    last_grad = {}

    def cost(theta) -> float:
        value, grad = _theta_cost_and_grad(jnp.asarray(theta, dtype), drive, batch, weights, param)
        last_grad["g"] = np.asarray(grad, dtype=np.float64)
        return float(value)

    t0 = time.perf_counter()
    cost(x0)
    first = time.perf_counter() - t0
    t0 = time.perf_counter()
    cost(x0)
    compile_s = max(first - (time.perf_counter() - t0), 0.0)
    recorder = _Recorder(cost, param, max_evaluations, callback)
    stopped = "converged"
    try:
        res = scipy.optimize.minimize(
            lambda th: (recorder(th), last_grad["g"]),
            x0,
            jac=True,
            method="L-BFGS-B",
            bounds=[(param.log_lower, param.log_upper)] * n,
            options={"maxfun": max_evaluations, "maxiter": max_evaluations},
        )
        stopped = "converged" if res.success else str(res.message)
    except _BudgetSpent:
        stopped = "max_evaluations"
    return recorder.result("l-bfgs-b", drive, compile_s, stopped)
