"""How fast the simulator runs on this machine (``pmsmjax bench``): the book drive (10 kHz, 10 RK4
sub-steps) in the process's precision (float32 unless x64 is enabled), every figure from one process.

1. compile time of ``simulate`` (first call minus a steady call), separately from run time;
2. control periods per second of one run (best of several repetitions, ``block_until_ready``), with any
   reference calls (a hand-written loop of the same scenario, say) timed in the same rounds;
3. periods per second over a ``vmap``'d batch of scenarios (speed steps 200-1500 r/min, loads 0-10 N m),
   and its compile time;
4. the reverse-mode gradient of a batch loss (mean ITAE of the speed error) with respect to the 7
   controller gains against the forward pass of the same loss, its compile time, and the same ratio at 1
   and 2 sub-steps per period;
5. forward- vs reverse-mode time of the ITAE gradient with respect to n parameters, for one scenario
   (n up to all 21 array leaves of the drive) and for the batch loss (n up to the 7 gains), and the
   crossover n of each (what
   [`pmsmjax.analysis.gradients.FORWARD_MODE_MAX_PARAMS`][pmsmjax.analysis.gradients.FORWARD_MODE_MAX_PARAMS]
   is chosen from). The two differ: in a batch each extra tangent costs about one more forward pass, while for
   one scenario extra tangents cost far less (scalar arithmetic leaves vector units idle, most likely);
6. the machine: CPU, core count, JAX version, backend.

Calls being compared are timed interleaved
([`time_interleaved`][pmsmjax.jobs.bench.time_interleaved]), so their ratios hold when another
process takes the CPU for a while. ``quick=True`` shrinks every size so the whole run takes seconds; its
timings mean nothing. The plain-text table of the figures is
[`pmsmjax.jobs.bench_report`][pmsmjax.jobs.bench_report].
"""

import dataclasses
import math
import os
import platform
import sys
import time
from collections.abc import Callable, Mapping

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from pmsmjax.analysis.gradients import value_and_grad
from pmsmjax.analysis.metrics import itae
from pmsmjax.assemble import part, with_parts
from pmsmjax.drive import Drive
from pmsmjax.jobs.bench_report import format_table
from pmsmjax.presets.three_phase import book_drive, book_scenario
from pmsmjax.scenarios import Scenario, stack_scenarios
from pmsmjax.simulate import simulate
from pmsmjax.units import rad_s_to_rpm

__all__ = [
    "FULL",
    "QUICK",
    "REQUIRED_KEYS",
    "BenchResult",
    "Sizes",
    "bench",
    "book_problem",
    "compile_time",
    "machine_info",
    "mode_crossover",
    "run",
    "time_interleaved",
]


@dataclasses.dataclass(frozen=True)
class Sizes:
    """How much work each measurement does.

    - `duration_s`: scenario length, s (4000 control periods at 0.4 s).
    - `batch`: scenarios in the throughput batch.
    - `grad_batch`: scenarios in the batch-gradient loss.
    - `reps`: timed rounds of the single run (and its reference calls) after the compiling call.
    - `slow_reps`: timed rounds of the batch run and the batch gradient.
    - `n_params`: parameter counts for the single-scenario forward- vs reverse-mode comparison.
    - `mode_reps`: timed rounds per count of that comparison.
    - `n_params_batch`: parameter counts (controller gains, so at most 7) for the same comparison on the
      ``grad_batch`` loss.
    - `batch_mode_reps`: timed rounds per count of the batch comparison.
    """

    duration_s: float
    batch: int
    grad_batch: int
    reps: int
    slow_reps: int
    n_params: tuple[int, ...]
    mode_reps: int
    n_params_batch: tuple[int, ...]
    batch_mode_reps: int


FULL = Sizes(
    duration_s=0.4,
    batch=256,
    grad_batch=64,
    reps=100,
    slow_reps=5,
    n_params=(1, 2, 3, 7, 13, 21),
    mode_reps=10,
    n_params_batch=(1, 2, 3, 4, 5, 7),
    batch_mode_reps=4,
)
# Compiling dominates the quick run, so it compares the modes at one parameter count, single scenario.
QUICK = Sizes(
    duration_s=0.05,
    batch=16,
    grad_batch=4,
    reps=3,
    slow_reps=2,
    n_params=(3,),
    mode_reps=2,
    n_params_batch=(),
    batch_mode_reps=2,
)

#: Keys [`run`][pmsmjax.jobs.bench.run] always returns.
REQUIRED_KEYS = (
    "periods_per_s_single",
    "periods_per_s_batch256",
    "compile_time_s",
    "batch_compile_time_s",
    "library_ms",
    "grad_batch64_s",
    "forward_batch64_s",
    "grad_over_forward_ratio",
    "grad_compile_time_s",
    "forward_vs_reverse",
    "mode_crossover_n_params",
    "machine",
)

# Every array leaf of the book drive, in the order subsets are taken for the forward/reverse comparison:
# the 7 controller gains, the plant's motor parameters, then the rest (limits, the controller's model;
# FOC does not use the model's J and B, so their gradients are zero, but they are still carried).
PARAMETERS: dict[str, str] = {
    "speed.kp": "controller.speed.kp",
    "speed.ki": "controller.speed.ki",
    "speed.active_damping": "controller.speed.active_damping",
    "current.kp_d": "controller.current.kp_d",
    "current.kp_q": "controller.current.kp_q",
    "current.ki_d": "controller.current.ki_d",
    "current.ki_q": "controller.current.ki_q",
    "motor.R": "machine.motor.R",
    "motor.L_d": "machine.motor.L_d",
    "motor.L_q": "machine.motor.L_q",
    "motor.psi_f": "machine.motor.psi_f",
    "motor.J": "machine.motor.J",
    "motor.B": "machine.motor.B",
    "current_limit": "controller.current_limit",
    "bridge.u_dc": "bridge.u_dc",
    "model.R": "controller.model.R",
    "model.L_d": "controller.model.L_d",
    "model.L_q": "controller.model.L_q",
    "model.psi_f": "controller.model.psi_f",
    "model.J": "controller.model.J",
    "model.B": "controller.model.B",
}
CONTROLLER_GAINS = tuple(PARAMETERS)[:7]


# ---------------------------------------------------------------------------------------------- timing


def _time_once(fn: Callable[[], object]) -> float:
    """Wall time (s) of ``fn()`` including waiting for its device results."""
    start = time.perf_counter()
    jax.block_until_ready(fn())
    return time.perf_counter() - start


def time_interleaved(calls: Mapping[str, Callable[[], object]], reps: int) -> tuple[dict, dict]:
    """Time each call once (compile + run), then ``reps`` rounds taking the calls in turn.

    Interleaving puts the calls being compared under the same machine load, so their ratio holds even
    when another process steals the CPU for a while. **Returns:** ``(first_s, best_s)`` dicts by name.
    """
    first = {name: _time_once(fn) for name, fn in calls.items()}
    best = dict.fromkeys(calls, math.inf)
    for _ in range(reps):
        for name, fn in calls.items():
            best[name] = min(best[name], _time_once(fn))
    return first, best


def compile_time(first_s: float, steady_s: float) -> float:
    """Compile (and trace) time, s: the first call minus a steady call."""
    return max(first_s - steady_s, 0.0)


def machine_info() -> dict:
    """Where the figures were taken: CPU, core count, Python/JAX versions, backend and device."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            names = [line.split(":", 1)[1].strip() for line in f if line.startswith("model name")]
        cpu = names[0] if names else cpu
    except OSError:
        pass
    return {
        "cpu": cpu,
        "cpu_count": os.cpu_count(),
        "platform": platform.platform(),
        "python": sys.version.split()[0],
        "jax": jax.__version__,
        "backend": jax.default_backend(),
        "device": str(jax.devices()[0].device_kind),
    }


# ---------------------------------------------------------------------------------- problem definition


def book_problem(sizes: Sizes) -> tuple[Drive, Scenario]:
    """The timed drive and scenario: the book drive, a 1000 r/min step with 10 N m at half of
    ``sizes.duration_s``."""
    return book_drive(), book_scenario(load_time_s=sizes.duration_s / 2, duration_s=sizes.duration_s)


def batch_of_scenarios(n: int, duration_s: float, seed: int = 0) -> Scenario:
    """``n`` book scenarios stacked: speed steps uniform in 200-1500 r/min, loads uniform in 0-10 N m.

    The load steps at half of ``duration_s`` (s).
    """
    rng = np.random.default_rng(seed)
    speeds = rng.uniform(200.0, 1500.0, n)
    loads = rng.uniform(0.0, 10.0, n)
    return stack_scenarios(
        [
            book_scenario(float(w), float(tl), load_time_s=duration_s / 2, duration_s=duration_s)
            for w, tl in zip(speeds, loads, strict=True)
        ]
    )


def get_parameters(drive: Drive, names) -> dict[str, jax.Array]:
    """The named leaves of ``drive`` (keys of `PARAMETERS`) as a dict of scalar arrays."""
    return {name: part(drive, PARAMETERS[name]) for name in names}


def with_parameters(drive: Drive, params: dict[str, jax.Array]) -> Drive:
    """``drive`` with the named leaves replaced by the values in ``params``."""
    return with_parts(drive, {PARAMETERS[name]: value for name, value in params.items()})


def speed_itae(drive: Drive, scenario: Scenario) -> jax.Array:
    """ITAE of the speed error over one scenario, rad/s * s^2."""
    trace = simulate(drive, scenario)
    return itae(trace.t, trace.speed_ref - trace.omega_m)


def batch_speed_itae(drive: Drive, scenarios: Scenario) -> jax.Array:
    """Mean speed-error ITAE over a stacked batch of scenarios, rad/s * s^2."""
    return jnp.mean(jax.vmap(lambda s: speed_itae(drive, s))(scenarios))


def parameter_itae(params: dict, drive: Drive, scenario: Scenario) -> jax.Array:
    """Speed ITAE (rad/s * s^2) of ``drive`` with the leaves in ``params`` substituted."""
    return speed_itae(with_parameters(drive, params), scenario)


def parameter_batch_itae(params: dict, drive: Drive, scenarios: Scenario) -> jax.Array:
    """Mean speed ITAE (rad/s * s^2) over ``scenarios`` of ``drive`` with ``params`` substituted."""
    return batch_speed_itae(with_parameters(drive, params), scenarios)


# ---------------------------------------------------------------------------------------- measurements


def measure_single(
    drive: Drive, scenario: Scenario, reps: int, references: Mapping[str, Callable[[], object]] | None = None
) -> dict:
    """One ``simulate`` call, timed interleaved with the `references` (zero-argument calls by name).

    Times in ms, compile time in s, rate in periods/s; ``references_ms`` (when there are references):
    the best time of each, ms (their compile times are not reported).
    """
    references = dict(references or {})
    if "library" in references:
        raise ValueError("a reference call may not be named 'library' (the simulator's own call)")
    first, best = time_interleaved({"library": lambda: simulate(drive, scenario), **references}, reps)
    omega = np.asarray(simulate(drive, scenario).omega_m)
    figures = {
        "compile_time_s": compile_time(first["library"], best["library"]),
        "library_ms": 1e3 * best["library"],
        "periods_per_s_single": scenario.n_periods(drive.Ts) / best["library"],
        "peak_speed_rpm": float(rad_s_to_rpm(np.max(np.abs(omega)))),
    }
    if references:
        figures["references_ms"] = {name: 1e3 * best[name] for name in references}
    return figures


def measure_batch(drive: Drive, scenarios: Scenario, reps: int) -> dict:
    """Compile time (s) and periods/s (total over the batch) of ``vmap(simulate)`` with a fixed drive.

    The whole Trace of every scenario is returned, as a user of ``vmap(simulate)`` gets it.
    """
    batched = eqx.filter_jit(eqx.filter_vmap(simulate, in_axes=(None, 0)))
    first, best = time_interleaved({"batch": lambda: batched(drive, scenarios)}, reps)
    size = scenarios.speed_ref.values.shape[0]
    return {
        "batch_size": size,
        "batch_compile_time_s": compile_time(first["batch"], best["batch"]),
        "batch_run_s": best["batch"],
        "periods_per_s_batch256": size * scenarios.n_periods(drive.Ts) / best["batch"],
    }


def measure_batch_gradient(drive: Drive, scenarios: Scenario, reps: int) -> dict:
    """Reverse-mode gradient of the batch ITAE w.r.t. the 7 controller gains vs the loss alone, s."""
    forward = jax.jit(parameter_batch_itae)
    gradient = jax.jit(lambda p, d, s: value_and_grad(parameter_batch_itae, p, d, s, mode="reverse"))
    gains = get_parameters(drive, CONTROLLER_GAINS)
    calls = {
        "forward": lambda: forward(gains, drive, scenarios),
        "grad": lambda: gradient(gains, drive, scenarios),
    }
    first, best = time_interleaved(calls, reps)
    _, grads = gradient(gains, drive, scenarios)
    return {
        "grad_batch_size": scenarios.speed_ref.values.shape[0],
        "forward_batch64_s": best["forward"],
        "forward_batch64_compile_time_s": compile_time(first["forward"], best["forward"]),
        "grad_batch64_s": best["grad"],
        "grad_compile_time_s": compile_time(first["grad"], best["grad"]),
        "grad_over_forward_ratio": best["grad"] / best["forward"],
        "grad_all_finite": bool(all(np.isfinite(np.asarray(g)) for g in grads.values())),
    }


def measure_modes(loss: Callable, drive: Drive, scenario: Scenario, n_params: int, reps: int) -> dict:
    """Forward- and reverse-mode gradient of ``loss`` w.r.t. the first ``n_params`` leaves of PARAMETERS.

    ``loss(params, drive, scenario)`` is `parameter_itae` or `parameter_batch_itae`. Times
    (s) via [`pmsmjax.analysis.gradients.value_and_grad`][pmsmjax.analysis.gradients.value_and_grad];
    ``grad_rel_diff`` is the largest difference between the two gradients relative to the largest reverse-mode
    component.
    """
    params = get_parameters(drive, tuple(PARAMETERS)[:n_params])
    fns = {
        mode: jax.jit(lambda p, d, s, mode=mode: value_and_grad(loss, p, d, s, mode=mode))
        for mode in ("forward", "reverse")
    }
    calls = {mode: (lambda fn=fn: fn(params, drive, scenario)) for mode, fn in fns.items()}
    first, best = time_interleaved(calls, reps)
    g_fwd, g_rev = (np.array(list(calls[mode]()[1].values())) for mode in ("forward", "reverse"))
    return {
        "n_params": n_params,
        "forward_s": best["forward"],
        "reverse_s": best["reverse"],
        "forward_compile_s": compile_time(first["forward"], best["forward"]),
        "reverse_compile_s": compile_time(first["reverse"], best["reverse"]),
        "grad_rel_diff": float(np.max(np.abs(g_fwd - g_rev)) / np.max(np.abs(g_rev))),
    }


def mode_crossover(rows: list[dict]) -> int:
    """Largest measured parameter count up to which forward mode beat reverse mode at every count.

    0 when reverse mode wins already at the smallest count. When forward mode wins at every measured
    count the true crossover lies above the largest one (see ``crossover_bracketed`` in
    [`run`][pmsmjax.jobs.bench.run]).
    """
    crossover = 0
    for row in sorted(rows, key=lambda r: r["n_params"]):
        if row["forward_s"] >= row["reverse_s"]:
            break
        crossover = row["n_params"]
    return crossover


# ------------------------------------------------------------------------------------------ the report


def run(quick: bool = False, references: Mapping[str, Callable[[], object]] | None = None) -> dict:
    """Run every measurement and return the figures (see the module docstring).

    **Arguments:**

    - `quick`: the `QUICK` sizes instead of `FULL`.
    - `references`: calls to time in the same rounds as the single run, by name (e.g. a hand-written loop
      of [`book_problem`][pmsmjax.jobs.bench.book_problem]'s scenario); their best times are
      ``references_ms``.

    Runs in the process's default precision: float32 unless x64 is enabled; ``dtype`` records which. The
    precision is not switched here because modules build constant tables at import in the precision of
    that moment. Times in s unless the key ends in ``_ms``; rates in control periods per second. The
    batch keys keep their full-size names (``..._batch256``, ``..._batch64_s``) in quick mode;
    ``batch_size`` and ``grad_batch_size`` give the sizes used.
    """
    sizes = QUICK if quick else FULL
    drive, scenario = book_problem(sizes)
    single = measure_single(drive, scenario, sizes.reps, references)
    batch = measure_batch(drive, batch_of_scenarios(sizes.batch, sizes.duration_s), sizes.slow_reps)
    grad_scenarios = batch_of_scenarios(sizes.grad_batch, sizes.duration_s, seed=1)
    grad = measure_batch_gradient(drive, grad_scenarios, sizes.slow_reps)
    modes = [measure_modes(parameter_itae, drive, scenario, n, sizes.mode_reps) for n in sizes.n_params]
    batch_modes = [
        measure_modes(parameter_batch_itae, drive, grad_scenarios, n, sizes.batch_mode_reps)
        for n in sizes.n_params_batch
    ]
    # The sub-step loop dominates the reverse pass (its transposed scan costs ~7x its forward per
    # iteration on XLA:CPU), so the ratio is also measured at the sub-step counts RK4 needs for accuracy
    # at 10 kHz (1 sub-step: 4e-7 of peak current against scipy, tests/machines/test_machines.py).
    by_substeps = []
    for n_sub in (1, 2):
        g = measure_batch_gradient(book_drive(n_substeps=n_sub), grad_scenarios, sizes.slow_reps)
        by_substeps.append(
            {
                "n_substeps": n_sub,
                "forward_s": g["forward_batch64_s"],
                "grad_s": g["grad_batch64_s"],
                "ratio": g["grad_over_forward_ratio"],
            }
        )
    crossover = mode_crossover(modes)
    return {
        "quick": quick,
        "dtype": str(drive.machine.motor.R.dtype),
        "drive": {"Ts_s": drive.Ts, "n_substeps": drive.n_substeps, "duration_s": sizes.duration_s},
        "n_periods": scenario.n_periods(drive.Ts),
        **single,
        **batch,
        **grad,
        "grad_over_forward_by_substeps": by_substeps,
        "forward_vs_reverse": modes,
        "mode_crossover_n_params": crossover,
        "crossover_bracketed": crossover < max(sizes.n_params),
        "forward_vs_reverse_batch64": batch_modes,
        "mode_crossover_n_params_batch64": mode_crossover(batch_modes) if batch_modes else None,
        "machine": machine_info(),
    }


@dataclasses.dataclass(frozen=True)
class BenchResult:
    """What ``pmsmjax bench`` gives its writer: `figures` ([`run`][pmsmjax.jobs.bench.run]'s dict, the JSON
    file's content) and `table` (their plain-text table for the console,
    [`pmsmjax.jobs.bench_report.format_table`][pmsmjax.jobs.bench_report.format_table])."""

    figures: dict
    table: str


def bench(quick: bool = False) -> BenchResult:
    """[`run`][pmsmjax.jobs.bench.run] (the `QUICK` sizes with ``quick``) and its table."""
    figures = run(quick=quick)
    return BenchResult(figures=figures, table=format_table(figures))
