"""Monte Carlo robustness studies of a drive, chunked, sharded over every device, resumable.

``run_study(study, out_dir)``:

1. checks the study and draws every run's parameters on the host (seeded, float64,
   [`distributions`][tuning.montecarlo.distributions]), before anything compiles; non-physical samples are
   refused or clipped;
2. splits the runs into equal chunks of at most ``chunk_size`` runs (``"auto"``: from the device's free
   memory and the drive's bytes per run, [`chunking`][tuning.montecarlo.chunking]), each rounded up to two
   runs per device; the last chunk is padded with copies of its last run, whose results are dropped;
3. runs each chunk as one compiled call: ``vmap`` of [`run_metrics`][tuning.montecarlo.kernel.run_metrics]
   over the chunk, the chunk's runs split over a one-axis device mesh with ``jax.sharding``
   (``NamedSharding`` over axis ``runs``). The same code serves one CPU, several forced CPU devices
   (``XLA_FLAGS=--xla_force_host_platform_device_count=N`` or ``jax_num_cpu_devices``), several GPUs and
   several hosts after ``jax.distributed.initialize()`` (every process draws the same samples, feeds its own
   devices' shards, and process 0 writes the files);
4. dispatches each chunk before fetching the previous one, so that copying a chunk's results to the host
   and writing its file overlap the next chunk's computation; results go straight into arrays allocated
   once for all runs;
5. writes each finished chunk to ``DIR/chunks/chunk_NNNNN.npz`` atomically, tagged with a fingerprint
   of the study, the samples, the precision and the code's version of the metrics; a rerun of the same
   study loads the chunks it finds and computes only the missing ones, so an interrupted study finishes
   where it stopped with the same results;
6. differentiates every metric by every varied parameter in forward mode (``jax.jacfwd``: one tangent per
   parameter) for the first ``sensitivity_runs`` runs (stored as ``DIR/chunks/sensitivities.npz``);
7. summarises ([`summary`][tuning.montecarlo.summary]), draws ([`figures`][tuning.montecarlo.figures]), writes
   ``DIR/summary.json``.

Run time is the wall time from the first chunk dispatched in this invocation until the last one's
results are on the host (compile excluded: each chunk function is compiled ahead of time and timed
separately as ``compile_time_s``; the file writes that overlap computation are inside it).
"""

import hashlib
import json
import math
import time
from collections.abc import Callable
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec
from tqdm import tqdm

from pmsmjax.analysis import observer_errors as om
from pmsmjax.io.logs import atomic_write
from pmsmjax.jobs.estimator_comparison import handover_settled_s
from pmsmjax.machines.integrate import max_stable_substep
from pmsmjax.simulate import check_simulation, period_inputs
from pmsmjax.spec.validation import ParameterError
from pmsmjax.units import rpm_to_rad_s
from tuning.montecarlo import physical_range
from tuning.montecarlo import study as mc_study
from tuning.montecarlo.chunk_files import load_agreed
from tuning.montecarlo.chunking import auto_chunk_size, bytes_per_run
from tuning.montecarlo.distributions import sample
from tuning.montecarlo.kernel import METRICS, OBSERVER_METRICS, run_metrics
from tuning.montecarlo.study import Study
from tuning.montecarlo.summary import sensitivity_summary, summarise
from tuning.parameters import set_leaves

#: Bump when the kernel's metric definitions change: chunks written by another version are recomputed.
KERNEL_VERSION = 1
#: The forward function's first output: these columns, stacked (one transfer per chunk, not eight);
#: a study with an observer has `OBSERVER_COLUMNS`.
COLUMNS = METRICS + ("finite",)
OBSERVER_COLUMNS = METRICS + OBSERVER_METRICS + ("finite",)
#: Keys of summary.json that describe how (fast) the study ran rather than its results.
VOLATILE_KEYS = (
    "run_time_s",
    "compile_time_s",
    "runs_per_s",
    "sensitivity_time_s",
    "linear_stability_time_s",
    "devices",
    "chunks",
    "chunk_rule",
)


def device_mesh() -> Mesh:
    """A one-axis mesh (``runs``) over every device of every process."""
    return Mesh(np.array(jax.devices()), ("runs",))


def chunk_layout(n: int, chunk_size: int, n_devices: int) -> tuple[int, int]:
    """``(chunk size, number of chunks)`` for ``n`` runs in chunks of at most ``chunk_size`` (rounded up
    to a multiple of ``2 n_devices``), balanced: as many chunks as that maximum needs, each as small as
    that count allows (10,000 runs at 2048: 5 chunks of 2000, not 4 of 2048 and a fifth padded by 240).

    At least two runs per device: with a batch of one, XLA compiles scalar code whose rounding differs in
    the last bit from the vectorised code of larger batches (observed), and results would then depend on
    the device count. From two runs up they are bitwise identical (tests/tuning/test_montecarlo.py).
    """
    unit = 2 * n_devices
    largest = -(-min(chunk_size, n) // unit) * unit
    count = -(-n // largest)
    per_chunk = -(-n // count)
    size = -(-per_chunk // unit) * unit
    return size, count


def _to_global(x: np.ndarray, sharding: NamedSharding) -> jax.Array:
    """A host array (identical on every process) as a global array sharded along its first axis."""
    return jax.make_array_from_callback(x.shape, sharding, lambda index: x[index])


def _to_host(x: jax.Array) -> np.ndarray:
    if jax.process_count() > 1:
        from jax.experimental import multihost_utils

        return np.asarray(multihost_utils.process_allgather(x, tiled=True))
    return np.asarray(x)


class StudyRunner:
    """The compiled pieces of one study: the nominal drive, the sample names and the sharded functions."""

    def __init__(self, study: Study, mesh: Mesh | None = None):
        self.study = study
        self.drive = mc_study.build_drive(study)
        self.names = tuple(study.parameters)
        self.mesh = device_mesh() if mesh is None else mesh
        self.sharding = NamedSharding(self.mesh, PartitionSpec("runs"))
        self.dtype = self.drive.machine.motor.R.dtype
        self.columns = COLUMNS if study.estimator is None else OBSERVER_COLUMNS
        study_, drive, names, columns = study, self.drive, self.names, self.columns
        if study.n_periods % study.decimate:
            raise ParameterError(
                f"study decimate = {study.decimate} must divide the {study.n_periods} periods of the run."
            )

        # observer figures from the end of the drive's own I/f hand-over (a drive file's start-up may last
        # longer than the book's, and the figures after convergence would count the blend itself)
        after = om.CONVERGED_AFTER_S if study.estimator is None else handover_settled_s(drive)

        def one(values):
            d, s = mc_study.apply_sample(drive, study_, names, values)
            return run_metrics(d, s, study_.load_time_s, decimate=study_.decimate, converged_after_s=after)

        def one_metrics(values):
            m, _ = one(values)
            return jnp.stack([m[k] for k in METRICS]), m["finite"]

        def jac(values):
            return jax.jacfwd(one_metrics, has_aux=True)(values)

        def packed(values):
            m, record = one(values)
            return jnp.stack([m[k] for k in columns]), record

        self._packed = packed
        self._forward = jax.jit(jax.vmap(packed), in_shardings=self.sharding, out_shardings=self.sharding)
        self._jacobian = jax.jit(jax.vmap(jac), in_shardings=self.sharding, out_shardings=self.sharding)
        self._compiled = {}
        self.compile_time_s = 0.0

    def check(self, samples: dict | None = None) -> None:
        """The simulation checks of the nominal run (before compiling) and, given the ``samples``, the
        RK4 sub-step against the fastest electrical rate among the sampled motors and speeds."""
        d, s = mc_study.apply_sample(self.drive, self.study, (), ())
        check_simulation(d, s, self.study.decimate)
        if not samples:
            return
        motor = self.drive.machine.motor
        inductances = ("R", "L_d", "L_q") + motor.leakage_fields  # multi-phase: the leakage inductance
        # the motor with every sampled value at once (NumPy vectors as its leaves; no checks run)
        values = [samples.get(f"motor.{f}", np.asarray(getattr(motor, f))) for f in inductances]
        sampled = set_leaves(motor, inductances, values)
        speed = rpm_to_rad_s(np.max(np.abs(samples.get("scenario.speed_rpm", self.study.speed_rpm))))
        h_max = max_stable_substep(sampled, 1.5 * speed + 1.0)  # the margin check_simulation allows
        if self.drive.Ts / self.drive.n_substeps > h_max:
            raise ParameterError(
                f"the sampled motors and speeds need an RK4 sub-step <= {h_max:.3g} s (fastest R/L or "
                f"omega_e among the samples): set [drive] n_substeps >= {math.ceil(self.drive.Ts / h_max)} "
                "or narrow the R, L or speed spreads."
            )

    def compile(self, kind: str, rows: int):
        """The compiled ``forward`` or ``jacobian`` function for ``rows`` runs (compile time is summed)."""
        key = (kind, rows)
        if key not in self._compiled:
            start = time.perf_counter()
            fn = self._forward if kind == "forward" else self._jacobian
            spec = jax.ShapeDtypeStruct((rows, len(self.names)), self.dtype, sharding=self.sharding)
            self._compiled[key] = fn.lower(spec).compile()
            self.compile_time_s += time.perf_counter() - start
        return self._compiled[key]

    def _call(self, kind: str, values: np.ndarray):
        fn = self.compile(kind, values.shape[0])
        return fn(_to_global(values.astype(self.dtype), self.sharding))

    def dispatch(self, values: np.ndarray):
        """Start the forward runs of the rows of ``values (B, P)`` (B a multiple of two per device) and
        return at once (JAX dispatches asynchronously); [`fetch`][tuning.montecarlo.runner.StudyRunner.fetch]
        waits for the results."""
        return self._call("forward", values)

    def fetch(self, outputs) -> tuple[dict, dict]:
        """The host copies of [`dispatch`][tuning.montecarlo.runner.StudyRunner.dispatch]'s outputs:
        ``(metrics, record)`` as in [`forward`][tuning.montecarlo.runner.StudyRunner.forward]."""
        packed, record = jax.block_until_ready(outputs)
        packed = _to_host(packed)
        metrics = {k: packed[:, i] for i, k in enumerate(self.columns)}
        return metrics, jax.tree.map(_to_host, record)

    def forward(self, values: np.ndarray) -> tuple[dict, dict]:
        """Metrics (``{name: (B,)}``, ``finite`` included) and decimated record
        (``{name: (B, N / decimate)}``) of every row of ``values (B, P)`` (B a multiple of two per device)."""
        return self.fetch(self.dispatch(values))

    def output_shapes(self) -> tuple:
        """One run's outputs of the forward function, as shape structs: the stacked
        [`COLUMNS`][tuning.montecarlo.runner.COLUMNS] and the decimated record (from the study's settings:
        tracing the kernel for them would cost as much as lowering it; tests/tuning/test_scale.py checks them
        against ``jax.eval_shape``)."""
        n_record = self.study.n_periods // self.study.decimate
        record = {k: jax.ShapeDtypeStruct((n_record,), self.dtype) for k in ("speed_rpm", "i_q_a")}
        return jax.ShapeDtypeStruct((len(self.columns),), self.dtype), record

    def per_run_bytes(self) -> int:
        """Upper bound of one run's device memory
        ([`tuning.montecarlo.chunking.bytes_per_run`][tuning.montecarlo.chunking.bytes_per_run])."""
        d, s = mc_study.apply_sample(self.drive, self.study, (), ())
        carry = jax.eval_shape(d.init)
        varied = any(n.startswith("scenario.") for n in self.names)
        inputs = jax.eval_shape(lambda: period_inputs(s, d.Ts)) if varied else None
        return bytes_per_run(self.output_shapes(), len(self.names), self.dtype, carry, inputs)

    def chunk_size(self, n: int) -> tuple[int, dict]:
        """The study's ``chunk_size``, or with ``"auto"`` the rule of
        [`tuning.montecarlo.chunking`][tuning.montecarlo.chunking]; returns
        ``(runs per chunk before balancing, how it was chosen)``."""
        n_dev = len(self.mesh.devices.flat)
        if self.study.chunk_size != "auto":
            return self.study.chunk_size, {"rule": "given"}
        return auto_chunk_size(n, n_dev, self.per_run_bytes(), n_periods=self.study.n_periods)

    def jacobian(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``((B, n_metrics, P) derivatives, (B,) finite flags)`` for the rows of ``values``."""
        jac, finite = jax.block_until_ready(self._call("jacobian", values))
        return _to_host(jac), _to_host(finite)


# Settings that do not change the compiled functions (they only change the values fed to them).
_VALUE_SETTINGS = (
    "n",
    "seed",
    "sampling",
    "chunk_size",
    "nonphysical",
    "sensitivity_runs",
    "current_threshold_a",
    "tracking_threshold_rpm",
)
_RUNNERS: dict = {}


def _runner(study: Study, mesh: Mesh | None) -> StudyRunner:
    """A [`StudyRunner`][tuning.montecarlo.runner.StudyRunner] for ``study``, reused (with its compiled
    functions) across calls that differ only in sampled values, so re-running or extending a study in one
    process does not recompile."""
    settings = {k: v for k, v in vars(study).items() if k not in _VALUE_SETTINGS}
    settings["parameters"] = tuple(study.parameters)
    key = (repr(sorted(settings.items())), mesh, jax.config.jax_enable_x64)
    if key not in _RUNNERS:
        if len(_RUNNERS) >= 4:
            _RUNNERS.pop(next(iter(_RUNNERS)))
        _RUNNERS[key] = StudyRunner(study, mesh)
    runner = _RUNNERS[key]
    runner.study = study
    runner.compile_time_s = 0.0
    return runner


def _pad(x: np.ndarray, size: int) -> np.ndarray:
    """Rows of ``x`` padded to ``size`` with copies of its last row (valid, physical parameters)."""
    return np.concatenate([x, np.repeat(x[-1:], size - x.shape[0], axis=0)]) if x.shape[0] < size else x


def fingerprint(study: Study, drive, values: np.ndarray, dtype) -> str:
    """A hash of everything that determines the runs' results: the settings, the nominal drive's values
    (so an edited motor or gains file counts), the samples and the precision; not the chunking, the
    devices or the failure thresholds, which only enter the summary."""
    h = hashlib.sha256()
    for leaf in jax.tree.leaves(drive):
        h.update(np.asarray(leaf).tobytes())
    skip = ("chunk_size", "sensitivity_runs", "current_threshold_a", "tracking_threshold_rpm")
    settings = {k: v for k, v in vars(study).items() if k not in skip}
    h.update(repr((sorted(settings.items()), str(np.dtype(dtype)), KERNEL_VERSION)).encode())
    h.update(np.ascontiguousarray(values).tobytes())
    return h.hexdigest()[:16]


def run_study(
    study: Study,
    out_dir,
    *,
    progress: bool = True,
    figures: bool = True,
    after_chunk: Callable[[int], None] | None = None,
    mesh: Mesh | None = None,
) -> dict:
    """Run (or finish) ``study`` into ``out_dir``; returns the summary also written to summary.json (on
    process 0 of a multi-process run; the other processes compute their shards and return None).

    `after_chunk(k)` is called after chunk ``k`` has been written (to report, or to interrupt in tests).
    """
    out = Path(out_dir)
    runner = _runner(study, mesh)
    runner.check()
    if study.linear_stability:  # its scope checked on the nominal drive before any run or file
        from tuning.montecarlo.linear_stability import check_nominal

        check_nominal(runner.drive, study, mc_study.apply_sample)
    dists = mc_study.distributions(study, runner.drive)
    samples = sample(dists, study.n, study.seed, study.sampling)
    nonphysical = physical_range.enforce_physical(
        samples, {k: d.nominal for k, d in dists.items()}, study.nonphysical
    )
    runner.check(samples)
    values = np.stack([samples[k] for k in runner.names], axis=1)
    key = fingerprint(study, runner.drive, values, runner.dtype)
    n_dev = len(runner.mesh.devices.flat)
    largest, chunk_rule = runner.chunk_size(study.n)
    size, n_chunks = chunk_layout(study.n, largest, n_dev)
    writer = jax.process_index() == 0
    chunk_dir = out / "chunks"
    if writer:
        chunk_dir.mkdir(parents=True, exist_ok=True)

    results: dict = {}  # {name: (n,) or (n, N / decimate)} on the writer, filled chunk by chunk
    counts = {"computed": 0, "runs": 0}
    clock = {"run_time": 0.0, "busy_since": None, "fetched": None}
    bar = tqdm(total=n_chunks, disable=not progress, desc="montecarlo", unit="chunk", leave=False)

    def store(lo: int, hi: int, data: dict) -> None:
        for k, v in data.items():
            if k not in results:
                results[k] = np.empty((study.n,) + v.shape[1:], v.dtype)
            results[k][lo:hi] = v[: hi - lo]

    def finish(c: int, lo: int, hi: int, path: Path, chunk_key: str, outputs) -> None:
        """Wait for chunk ``c``'s results, keep them and write its file (while the next one computes)."""
        metrics, record = runner.fetch(outputs)
        clock["fetched"] = time.perf_counter()
        counts["computed"] += 1
        counts["runs"] += hi - lo
        if writer:
            data = {k: v[: hi - lo] for k, v in {**metrics, **record}.items()}
            store(lo, hi, data)
            tagged = {"fingerprint": np.asarray(chunk_key), **data}
            atomic_write(path, lambda f: np.savez(f, **tagged))

    def done(c: int) -> None:
        bar.update(1)
        if after_chunk is not None:
            after_chunk(c)

    pending = None  # (c, lo, hi, path, chunk_key, device outputs) of the chunk in flight
    try:
        for c in range(n_chunks):
            lo, hi = c * size, min((c + 1) * size, study.n)
            path = chunk_dir / f"chunk_{c:05d}.npz"
            chunk_key = f"{key}:{lo}:{hi - lo}"
            data = load_agreed(path, chunk_key, hi - lo)
            launched = None
            if data is None:
                runner.compile("forward", size)  # outside the timed region (a no-op after the first)
                if clock["busy_since"] is None:
                    clock["busy_since"] = time.perf_counter()
                launched = (c, lo, hi, path, chunk_key, runner.dispatch(_pad(values[lo:hi], size)))
            if pending is not None:
                finish(*pending)
                done(pending[0])
            if launched is None:
                if clock["busy_since"] is not None:  # nothing in flight any more: close the timed stretch
                    clock["run_time"] += clock["fetched"] - clock["busy_since"]
                    clock["busy_since"] = None
                if writer:
                    store(lo, hi, data)
                done(c)
            pending = launched
        if pending is not None:
            finish(*pending)
            clock["run_time"] += clock["fetched"] - clock["busy_since"]
            done(pending[0])
    finally:
        bar.close()
    computed, runs_now, run_time = counts["computed"], counts["runs"], clock["run_time"]
    results = results if writer else None

    n_sens = min(study.sensitivity_runs, study.n)
    sensitivities, sensitivity_time = None, None
    if n_sens:
        sens_path = chunk_dir / "sensitivities.npz"
        sens_key = f"{key}:sensitivities:{n_sens}"
        data = load_agreed(sens_path, sens_key, n_sens)
        if data is None:
            s_size, _ = chunk_layout(n_sens, n_sens, n_dev)
            padded = _pad(values[:n_sens], s_size)
            runner.compile("jacobian", s_size)
            start = time.perf_counter()
            jac, finite = runner.jacobian(padded)
            sens_time = time.perf_counter() - start
            data = {"jacobian": jac[:n_sens], "finite": finite[:n_sens], "time_s": np.asarray(sens_time)}
            if writer:
                atomic_write(sens_path, lambda f: np.savez(f, fingerprint=np.asarray(sens_key), **data))
        if writer:
            scales = {k: d.tolerance * d.nominal for k, d in dists.items()}
            sensitivities = sensitivity_summary(data["jacobian"], data["finite"], runner.names, scales)
            sensitivity_time = float(data["time_s"])

    linear_time = None
    if study.linear_stability and writer:
        from tuning.montecarlo.linear_stability import spectral_radii

        results["spectral_radius"], linear_time = spectral_radii(
            runner.drive, study, runner.names, values, mc_study.apply_sample
        )
    if not writer:
        return None
    summary = {
        "n_runs": study.n,
        "run_time_s": run_time,
        "compile_time_s": runner.compile_time_s,
        "runs_per_s": runs_now / run_time if run_time > 0 else None,
        "sensitivity_time_s": sensitivity_time,
        "chunks": {
            "size": size,
            "count": n_chunks,
            "computed_now": computed,
            "loaded": n_chunks - computed,
        },
        "chunk_rule": chunk_rule,
        "devices": {
            "count": n_dev,
            "kind": str(runner.mesh.devices.flat[0].device_kind),
            "processes": jax.process_count(),
        },
        "study": {k: v for k, v in vars(study).items() if k != "parameters"},
        "drive_file": study.spec.summary(),
        "parameters": {k: d.describe() for k, d in dists.items()},
        "nonphysical_samples": {"mode": study.nonphysical, "counts": nonphysical},
        "precision": str(np.dtype(runner.dtype)),
        **summarise(
            results,
            samples,
            current_threshold_a=study.current_threshold,
            tracking_threshold_rpm=study.tracking_threshold_rpm,
        ),
        "sensitivities": sensitivities,
    }
    if linear_time is not None:
        summary["linear_stability_time_s"] = linear_time
        summary["max_spectral_radius"] = float(np.max(results["spectral_radius"]))
    summary = _finite_or_none(summary)
    if figures:
        from tuning.montecarlo.figures import save_study_figures

        t = np.arange(results["speed_rpm"].shape[1]) * study.decimate * runner.drive.Ts
        summary["figures"] = [p.name for p in save_study_figures(results, summary, t, out)]
    text = json.dumps(summary, indent=2, allow_nan=False) + "\n"
    atomic_write(out / "summary.json", lambda f: f.write(text.encode()))
    return summary


def _finite_or_none(x):
    """JSON-ready copy: NumPy scalars as Python numbers, NaN/inf as null."""
    if isinstance(x, dict):
        return {k: _finite_or_none(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_finite_or_none(v) for v in x]
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, float) and not np.isfinite(x):
        return None
    return x
