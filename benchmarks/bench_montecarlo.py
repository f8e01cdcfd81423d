"""Monte Carlo throughput: N closed-loop runs of the book scenario against the same runs one by one.

Usage (from the repository root)::

    python -m benchmarks.bench_montecarlo                  # 10,000 runs, table + bench_montecarlo.json
    python -m benchmarks.bench_montecarlo --sweep          # also runs/s for several chunk sizes
    python -m benchmarks.bench_montecarlo --n 1000000      # on a GPU

What it measures, in one process:

1. ``run_study`` (what ``pmsmjax montecarlo`` does) on the default study: the book drive and scenario
   (1000 r/min step, 10 N m load step at 0.2 s, 0.4 s = 4000 periods at 10 kHz, 10 RK4 sub-steps) with
   R, L_d, L_q, psi_f, J, B and U_dc drawn from their default tolerances; no sensitivities, no figures.
   ``run_time_s`` is the time of the chunk calls (execution and the transfer of results to the host),
   ``compile_time_s`` the ahead-of-time compile, ``wall_time_s`` the whole call (sampling, files, summary).
2. The same kernel unbatched, one jit call per run, on the first ``--one-by-one`` runs (default 20), after
   its compile; the time for all N runs is *extrapolated* from their mean (running 10,000 of them one by
   one would take minutes). The ratio is that extrapolated time over the batched run time.
3. With ``--sweep``: runs/s of a chunk call for several chunk sizes (each compiled and timed twice).
4. The machine and the JAX device layout (on CPU the cores are split into devices first, as the
   ``pmsmjax montecarlo`` command does: ``--devices`` overrides, ``XLA_FLAGS`` set by you wins).

Precision is float32 (JAX's default) unless x64 is enabled.
"""

import argparse
import sys
import tempfile
import time

from tuning.montecarlo.cpu_devices import split_cpu


def _parse(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--n", type=int, default=10_000, help="runs (default 10000)")
    p.add_argument(
        "--chunk-size", type=int, default=None, help="most runs per chunk (default: auto, from device memory)"
    )
    p.add_argument("--one-by-one", type=int, default=20, help="runs timed one by one (default 20)")
    p.add_argument("--sweep", action="store_true", help="also time chunk sizes 256..8192")
    p.add_argument("--devices", type=int, default=None, help="CPU devices (default: one per core)")
    p.add_argument("--unroll-substeps", action="store_true", help="RK4 sub-steps unrolled (for GPUs)")
    p.add_argument(
        "--json", default="bench_montecarlo.json", help="output JSON (default bench_montecarlo.json)"
    )
    return p.parse_args(argv)


def one_by_one(study, values, k: int) -> dict:
    """Mean time (s) of one unbatched jit call per run over the first ``k`` rows of ``values``."""
    import jax
    import numpy as np

    from tuning.montecarlo import study as mc_study
    from tuning.montecarlo.kernel import run_metrics

    drive = mc_study.build_drive(study)
    names = tuple(study.parameters)

    @jax.jit
    def one(v):
        d, s = mc_study.apply_sample(drive, study, names, v)
        return run_metrics(d, s, study.load_time_s, decimate=study.decimate)

    rows = values[:k].astype(np.float32 if not jax.config.jax_enable_x64 else np.float64)
    start = time.perf_counter()
    jax.block_until_ready(one(rows[0]))
    compile_s = time.perf_counter() - start
    start = time.perf_counter()
    for row in rows:
        jax.block_until_ready(one(row))
    per_run = (time.perf_counter() - start) / len(rows)
    return {
        "one_by_one_runs_timed": len(rows),
        "one_by_one_s_per_run": per_run,
        "one_by_one_compile_s": compile_s,
    }


def sweep(study, values, sizes) -> list[dict]:
    """runs/s of one chunk call per chunk size (best of two after compiling)."""
    import numpy as np

    from tuning.montecarlo import StudyRunner, chunk_layout

    rows = []
    for size in sizes:
        runner = StudyRunner(study)
        size, _ = chunk_layout(size, size, len(runner.mesh.devices.flat))
        x = np.resize(values, (size, values.shape[1]))
        runner.compile("forward", size)
        best = np.inf
        for _ in range(2):
            start = time.perf_counter()
            runner.forward(x)
            best = min(best, time.perf_counter() - start)
        rows.append(
            {
                "chunk_size": size,
                "chunk_s": best,
                "runs_per_s": size / best,
                "compile_s": runner.compile_time_s,
            }
        )
        print(
            f"  chunk {size:6d}: {size / best:8.0f} runs/s ({best:.3f} s per chunk, "
            f"compile {runner.compile_time_s:.1f} s)"
        )
    return rows


def run(
    n: int = 10_000,
    chunk_size: int | None = None,
    k_one: int = 20,
    do_sweep: bool = False,
    unroll_substeps: bool = False,
) -> dict:
    import numpy as np

    from benchmarks.bench_core import machine_info
    from tuning.montecarlo import run_study
    from tuning.montecarlo import study as mc_study
    from tuning.montecarlo.distributions import sample

    if chunk_size is None:
        chunk_size = mc_study.Study.chunk_size  # "auto": tuning.montecarlo.chunking
    study = mc_study.Study(n=n, chunk_size=chunk_size, sensitivity_runs=0, unroll_substeps=unroll_substeps)
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        summary = run_study(study, tmp, progress=False, figures=False)
        wall = time.perf_counter() - start
    drive = mc_study.build_drive(study)
    dists = mc_study.distributions(study, drive)
    samples = sample(dists, study.n, study.seed, study.sampling)
    values = np.stack([samples[k] for k in study.parameters], axis=1)
    periods = study.n_periods
    out = {
        "n_runs": n,
        "n_periods_per_run": periods,
        "n_substeps": study.n_substeps,
        "unroll_substeps": unroll_substeps,
        "chunk_size": summary["chunks"]["size"],
        "n_chunks": summary["chunks"]["count"],
        "devices": summary["devices"],
        "dtype": summary["precision"],
        "run_time_s": summary["run_time_s"],
        "compile_time_s": summary["compile_time_s"],
        "wall_time_s": wall,
        "runs_per_s": n / summary["run_time_s"],
        "periods_per_s": n * periods / summary["run_time_s"],
        "failure_rate": summary["failures"]["any"]["rate"],
        "itae_p50": summary["metrics"]["itae"]["p50"],
    }
    out.update(one_by_one(study, values, min(k_one, n)))
    out["one_by_one_extrapolated_s"] = out["one_by_one_s_per_run"] * n
    out["speedup_vs_one_by_one"] = out["one_by_one_extrapolated_s"] / out["run_time_s"]
    if do_sweep:
        print("chunk-size sweep:")
        out["sweep"] = sweep(study, values, (256, 512, 1024, 2048, 4096, 8192))
    out["machine"] = machine_info()
    return out


def format_table(r: dict) -> str:
    dev = r["devices"]
    rows = [
        ("runs x periods (sub-steps)", f"{r['n_runs']} x {r['n_periods_per_run']} ({r['n_substeps']})"),
        ("devices", f"{dev['count']} x {dev['kind']}, {r['dtype']}"),
        ("chunks", f"{r['n_chunks']} of {r['chunk_size']}"),
        ("run time (compile excluded)", f"{r['run_time_s']:.2f} s"),
        ("compile time", f"{r['compile_time_s']:.1f} s"),
        ("whole run_study call", f"{r['wall_time_s']:.2f} s"),
        ("throughput", f"{r['runs_per_s']:.0f} runs/s, {r['periods_per_s'] / 1e6:.2f} M periods/s"),
        (
            "one by one (extrapolated)",
            f"{r['one_by_one_s_per_run'] * 1e3:.1f} ms/run x {r['n_runs']} = "
            f"{r['one_by_one_extrapolated_s']:.1f} s "
            f"(from {r['one_by_one_runs_timed']} runs)",
        ),
        ("batched speed-up vs one by one", f"{r['speedup_vs_one_by_one']:.1f} x"),
        ("failure rate, ITAE p50", f"{100 * r['failure_rate']:.2f} %, {r['itae_p50']:.4f} rad s"),
        ("machine", f"{r['machine']['cpu']} ({r['machine']['cpu_count']} cores), jax {r['machine']['jax']}"),
    ]
    width = max(len(k) for k, _ in rows)
    return "\n".join(f"{k:<{width}}  {v}" for k, v in rows)


def main(argv=None) -> dict:
    args = _parse(argv)
    split_cpu(args.devices)
    from benchmarks.bench_core import publish

    results = run(args.n, args.chunk_size, args.one_by_one, args.sweep, args.unroll_substeps)
    return publish(results, format_table(results), args.json)


if __name__ == "__main__":
    main(sys.argv[1:])
