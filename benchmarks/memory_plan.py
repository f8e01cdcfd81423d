"""The commands' memory plans ([`pmsmjax.cli.memory`][pmsmjax.cli.memory]) against their measured peak RSS.

Each case runs one ``pmsmjax`` command in a fresh subprocess (``--max-memory-gb 1000``: the plan does not
refuse) and prints the plan's estimate, the measured peak resident memory (``ru_maxrss`` of the child) and
their ratio; the plan is meant to hold within a factor of 1.5 either way. The logs of ``identify`` and
``replay`` are the book drive's identification run, simulated once and repeated (time shifted) to the
row count, written to a temporary folder.

Run: ``python -m benchmarks.memory_plan [--quick]`` (Linux; several minutes on 2 cores).
"""

import argparse
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from pmsmjax.cli import memory

REPO = Path(__file__).resolve().parents[1]


def peak_rss(argv: list[str]) -> tuple[int, float, int]:
    """Run ``python -m pmsmjax argv`` in a subprocess; returns (peak RSS bytes, wall s, exit status)."""
    code = (
        "import resource, subprocess, sys; r = subprocess.run(sys.argv[1:]); "
        "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024); sys.exit(r.returncode)"
    )
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    t0 = time.perf_counter()
    out = subprocess.run(
        [sys.executable, "-c", code, sys.executable, "-m", "pmsmjax", *argv, "--max-memory-gb", "1000"],
        capture_output=True,
        text=True,
        env=env,
        cwd=REPO,
    )
    wall = time.perf_counter() - t0
    if out.returncode:
        print(out.stderr[-2000:], file=sys.stderr)
    return int(out.stdout.strip().splitlines()[-1]), wall, out.returncode


def identification_log_rows(rows: int, path: Path) -> None:
    """A dq log of `rows` rows: the book identification run (2 s), repeated with the time shifted."""
    from pmsmjax.io.logs import write_csv_atomic
    from pmsmjax.recorded.synthetic_logs import identification_log
    from tuning.identify import identification_scenario

    base = identification_log(identification_scenario())
    n = len(base["time"])
    reps = -(-rows // n)
    dt = float(base["time"][1] - base["time"][0])
    cols = {}
    for k, v in base.items():
        v = np.asarray(v, np.float64)
        if k == "time":
            cols[k] = (np.arange(n * reps) * dt)[:rows]
        else:
            cols[k] = np.tile(v, reps)[:rows]
    write_csv_atomic(path, cols)


def main(argv=None) -> int:
    """Print estimate against measured peak RSS for each case."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="the smallest case of each command only")
    args = parser.parse_args(argv)
    Ts = 1e-4  # the book drive's control period, s
    from pmsmjax.trace import COLUMN_UNITS

    n_cols = len(COLUMN_UNITS)
    demo_cases = [(4.0, 1), (20.0, 1), (40.0, 1), (40.0, 100), (200.0, 100)]
    mc_cases = [20_000, 100_000, 400_000]
    log_cases = [100_000, 400_000]
    if args.quick:
        demo_cases, mc_cases, log_cases = demo_cases[:1], mc_cases[:1], log_cases[:1]
    print(f"machine: {platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}")
    print(f"{'case':58s} {'estimate':>9s} {'measured':>9s} {'ratio':>6s} {'wall':>7s}")
    rows = []

    def report(name, estimate, argv):
        peak, wall, rc = peak_rss(argv)
        ratio = estimate / peak
        rows.append(ratio)
        flag = "" if rc == 0 else f"  (exit {rc})"
        print(
            f"{name:58s} {estimate / 1e9:8.2f}G {peak / 1e9:8.2f}G {ratio:6.2f} {wall:6.1f}s{flag}",
            flush=True,
        )

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for duration, d in demo_cases:
            n = int(round(duration / Ts))
            est = memory.demo_bytes(n, d, n_cols)
            argv = ["demo", "--duration-s", str(duration), "--decimate", str(d), "--out", str(tmp / "demo")]
            report(f"demo --duration-s {duration:g} --decimate {d}", est, argv)
        cfg = tmp / "short.toml"
        cfg.write_text("[scenario]\nduration_s = 0.02\nload_time_s = 0.01\n[study]\ndecimate = 10\n")
        for n in mc_cases:
            # 200 periods per run, 6 parameters, 9 metric columns, 2 x 20 recorded values, chunks of 8192
            est = memory.montecarlo_bytes(n, 6, 9, 2 * 20, 8192)
            argv = [
                "montecarlo",
                "--n",
                str(n),
                "--config",
                str(cfg),
                "--no-progress",
                "--chunk-size",
                "8192",
            ]
            argv += ["--sensitivity-runs", "0", "--out", str(tmp / f"mc{n}")]
            report(f"montecarlo --n {n:,} (0.02 s runs)", est, argv)
        for n in log_cases:
            log = tmp / f"log{n}.csv"
            identification_log_rows(n, log)
            for command in ("replay", "identify"):
                est = memory.log_fit_bytes(command, n)
                argv = [command, str(log), "--out", str(tmp / command)]
                argv += ["--motor", "book"] if command == "replay" else ["--pole-pairs", "4", "--no-figures"]
                report(f"{command} of a {n:,}-row CSV log", est, argv)
            log.unlink()
    print(f"estimate / measured: {min(rows):.2f} to {max(rows):.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
