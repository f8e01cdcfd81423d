"""The commissioning chain on a drive that is not the book's, as a user runs it, timed step by step:

1. a noisy closed-loop log of the drive, made without the engine
   ([`tuning.identify.reference_log`][tuning.identify.reference_log]: NumPy FOC, SciPy DOP853 plant; 1 %
   current and 0.5 % voltage noise, as the identification tests);
2. ``pmsmjax identify LOG --motor PRIOR --out ID``: the motor with error bars, written as ID/motor.toml
   (the prior's ratings and inverter carried over);
3. ``pmsmjax tune --motor ID/motor.toml --robust --out TUNE``: gains trained over plant draws from the
   identified tolerances;
4. ``pmsmjax montecarlo --motor ID/motor.toml --gains TUNE/gains.toml --out MC``;
5. ``pmsmjax demo --motor ID/motor.toml --gains TUNE/gains.toml --out DEMO``.

Prints the identified values against the truth (the bars: R 1 %, L 2 %, psi_f 0.5 %, J 3 %), each step's
wall time and the total, with the machine named. Each command runs in this process through
`pmsmjax.cli.main`, with its persistent compilation cache off (a first run).

``python -m benchmarks.commissioning_chain [--drive servo-400w] [--json FILE]``
"""

import argparse
import json
import tempfile
import time
from pathlib import Path

from benchmarks.bench_core import machine_info, publish
from pmsmjax.cli import main as pmsmjax
from pmsmjax.io.drive_files import drive_spec
from pmsmjax.io.logs import write_csv_atomic
from tuning.identify.reference_log import commissioning_log

#: The identify bars the chain must meet, relative.
BARS = {"R": 0.01, "L_d": 0.02, "L_q": 0.02, "psi_f": 0.005, "J": 0.03}
#: Log length, s, and PRBS bit on i_d, s, per drive (enough speed levels for J and B, a settled current
#: per bit).
LOG_SETTINGS = {"servo-400w": (0.4, 0.005), "outer-rotor-24v": (0.8, 0.005), "industrial-5k6w": (4.0, 0.02)}


def chain_log(name: str, seed: int = 0) -> dict:
    """The noisy identification log of preset drive ``name`` (module docstring, step 1)."""
    return commissioning_log(drive_spec(name), *LOG_SETTINGS[name], seed=seed)


def run_chain(name: str, folder: Path, *, tune_args=(), montecarlo_runs: int = 1000) -> dict:
    """Run the chain on preset drive ``name`` in ``folder``; returns the figures."""
    steps, times = {}, {}
    t0 = time.perf_counter()
    write_csv_atomic(folder / "log.csv", chain_log(name))
    times["log"] = time.perf_counter() - t0
    motor, gains = str(folder / "id" / "motor.toml"), str(folder / "tune" / "gains.toml")
    commands = {
        "identify": ["identify", str(folder / "log.csv"), "--motor", name, "--out", str(folder / "id")],
        "tune": ["tune", "--motor", motor, "--robust", "--out", str(folder / "tune"), "--no-progress"],
        "montecarlo": ["montecarlo", "--motor", motor, "--gains", gains, "--n", str(montecarlo_runs)],
        "demo": ["demo", "--motor", motor, "--gains", gains, "--out", str(folder / "demo"), "--no-figures"],
    }
    commands["tune"] += list(tune_args)
    commands["montecarlo"] += ["--out", str(folder / "mc"), "--no-progress", "--no-figures"]
    for step, argv in commands.items():
        t0 = time.perf_counter()
        status = pmsmjax([*argv, "--no-compile-cache"])
        times[step] = time.perf_counter() - t0
        steps[step] = status
        if status != 0:
            raise SystemExit(f"pmsmjax {' '.join(argv)} exited {status}")
    truth = drive_spec(name).motor
    found = drive_spec(folder / "id" / "motor.toml").motor
    errors = {k: found[k] / truth[k] - 1.0 for k in ("R", "L_d", "L_q", "psi_f", "J", "B")}
    tune = json.loads((folder / "tune" / "result.json").read_text())
    mc = json.loads((folder / "mc" / "summary.json").read_text())
    demo = json.loads((folder / "demo" / "summary.json").read_text())
    return {
        "drive": name,
        "relative_errors": errors,
        "within_bars": all(abs(errors[k]) <= bar for k, bar in BARS.items()),
        "tune_heldout_itae": {k: tune["heldout"][k]["itae"] for k in ("before", "after")},
        "montecarlo_failure_rate": mc["failures"]["any"]["rate"],
        "demo_final_speed_rpm": demo["metrics"]["final_speed_rpm"],
        "seconds": {**times, "total": sum(times.values())},
        "machine": machine_info(),
    }


def format_table(r: dict) -> str:
    rows = [f"commissioning chain on {r['drive']} ({r['machine'].get('cpu', '?')})"]
    rows += [f"  {k:6s} error {100 * v:+.3f} %  (bar {100 * BARS[k]:g} %)" if k in BARS else
             f"  {k:6s} error {100 * v:+.3f} %" for k, v in r["relative_errors"].items()]  # fmt: skip
    rows.append(f"  within the bars: {r['within_bars']}")
    it = r["tune_heldout_itae"]
    rows.append(f"  robust tune: held-out ITAE {it['before']:.4g} -> {it['after']:.4g} rad s")
    rows.append(f"  Monte Carlo failure rate {100 * r['montecarlo_failure_rate']:.2f} %")
    rows.append(f"  demo final speed {r['demo_final_speed_rpm']:.1f} r/min")
    rows += [f"  {k:10s} {v:7.1f} s" for k, v in r["seconds"].items()]
    return "\n".join(rows)


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--drive", default="servo-400w", choices=sorted(LOG_SETTINGS))
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as folder:
        results = run_chain(args.drive, Path(folder))
    return publish(results, format_table(results), args.json)


if __name__ == "__main__":
    main()
