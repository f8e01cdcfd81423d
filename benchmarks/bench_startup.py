"""Start-up of every command as a user meets it: the whole process, imports, compile, run, figures and
files, timed from outside with JAX's persistent compilation cache empty (a first run) and filled by an
earlier run of the same command (a repeated run).

Each command runs on small inputs that still exercise its whole path (the book demo as the README gives
it, without its figures, and on the measured flux map of the ``saturated-ipm`` drive file; a two-controller
compare; a two-iteration tune; a 64-run Monte Carlo study; identify, observe and
replay on a synthetic log written here). "first" is the best of `repeats` runs, each with a new empty
cache folder (``PMSMJAX_CACHE_DIR``); "cached" the best of `repeats` runs after one that filled the cache.
Their difference is what the cache saves; what remains of "cached" is imports, the run itself, figures
and files.

``python -m benchmarks.bench_startup [--commands demo,tune] [--repeats 3] [--json FILE]``.
"""

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.bench_core import machine_info, publish
from pmsmjax.io.logs import write_csv_atomic

#: name -> the command's arguments after ``pmsmjax`` (``{out}``: a fresh output folder; ``{log}``,
#: ``{stator_log}``: the synthetic logs).
COMMANDS = {
    "help": ["--help"],
    "demo": ["demo", "--out", "{out}"],
    "demo-no-figures": ["demo", "--no-figures", "--out", "{out}"],
    "demo-flux-map": ["demo", "--motor", "saturated-ipm", "--out", "{out}"],
    "compare": ["compare", "--control", "pi,smc", "--out", "{out}"],
    "pwm-compare": ["pwm-compare", "--out", "{out}"],
    "tune": [
        "tune",
        "--iterations",
        "2",
        "--train",
        "4",
        "--heldout",
        "4",
        "--no-progress",
        "--out",
        "{out}",
    ],
    "montecarlo": ["montecarlo", "--n", "64", "--no-progress", "--out", "{out}"],
    "identify": ["identify", "{log}", "--pole-pairs", "4", "--out", "{out}"],
    "observe": ["observe", "{stator_log}", "--motor", "book", "--observer", "smo", "--out", "{out}"],
    "replay": ["replay", "{log}", "--motor", "book", "--out", "{out}"],
}


def write_logs(folder: Path) -> dict:
    """A dq identification log and a stator-frame drive log of the book drive, as CSV files in `folder`."""
    from pmsmjax import presets
    from pmsmjax.recorded.synthetic_logs import drive_log, identification_log
    from tuning.identify import identification_scenario

    log = folder / "log.csv"
    write_csv_atomic(log, identification_log(identification_scenario(duration_s=0.5)))
    stator_log = folder / "stator_log.csv"
    write_csv_atomic(stator_log, drive_log(presets.book_drive(), presets.book_scenario(duration_s=0.3)))
    return {"log": str(log), "stator_log": str(stator_log)}


def time_command(args: list[str], cache: Path) -> float:
    """Wall time (s) of one ``python -m pmsmjax ARGS`` process with the cache folder `cache`; raises if
    the command fails."""
    env = {**os.environ, "PMSMJAX_CACHE_DIR": str(cache)}
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "pmsmjax", *args], env=env, capture_output=True, text=True)
    elapsed = time.perf_counter() - t0
    if done.returncode != 0:
        raise RuntimeError(f"pmsmjax {' '.join(args)} exited {done.returncode}: {done.stderr.strip()[-400:]}")
    return elapsed


def run(commands: list[str], repeats: int = 3) -> dict:
    """Best first-run and cached wall times (s) of each command in `commands`."""
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        files = write_logs(tmp)
        n_out = 0

        def args_for(name):
            nonlocal n_out
            n_out += 1
            return [a.format(out=tmp / f"out{n_out}", **files) for a in COMMANDS[name]]

        for name in commands:
            first = [time_command(args_for(name), tmp / f"cache-{name}-first{k}") for k in range(repeats)]
            warm = tmp / f"cache-{name}"
            time_command(args_for(name), warm)
            cached = [time_command(args_for(name), warm) for _ in range(repeats)]
            results[name] = {"first_s": min(first), "cached_s": min(cached), "args": COMMANDS[name]}
            print(f"{name:12s} first {min(first):6.2f} s   cached {min(cached):6.2f} s", flush=True)
    return {"commands": results, "repeats": repeats, "machine": machine_info()}


def format_table(r: dict) -> str:
    machine = r["machine"]
    lines = [
        f"whole process, best of {r['repeats']}; machine: {machine['cpu']}, {machine['cpu_count']} cores",
        f"{'command':12s} {'first run':>10s} {'cached':>8s}   arguments",
    ]
    for name, c in r["commands"].items():
        lines.append(
            f"{name:12s} {c['first_s']:8.2f} s {c['cached_s']:6.2f} s   pmsmjax {' '.join(c['args'])}"
        )
    return "\n".join(lines)


def main(json_path: str | None = None, commands: list[str] | None = None, repeats: int = 3) -> dict:
    results = run(commands or list(COMMANDS), repeats)
    return publish(results, format_table(results), json_path)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--commands", default=",".join(COMMANDS), help="comma-separated subset of: " + ", ".join(COMMANDS)
    )
    parser.add_argument("--repeats", type=int, default=3, help="runs per figure, best taken (default 3)")
    parser.add_argument("--json", default=None, help="write the figures to this JSON file")
    a = parser.parse_args()
    unknown = set(a.commands.split(",")) - set(COMMANDS)
    if unknown:
        parser.error(f"unknown command(s) {sorted(unknown)}: choose from {', '.join(COMMANDS)}")
    main(a.json, a.commands.split(","), a.repeats)
