"""Per-period cost of the six-phase drive against the three-phase book drive, in one run.

Every drive simulates the same book scenario (1000 r/min, 10 N m at 0.2 s, 0.4 s; float32 unless x64 is
enabled, as the command line runs), timed interleaved
([`benchmarks.bench_core.time_interleaved`][pmsmjax.jobs.bench.time_interleaved]) so the ratios
hold under a varying machine load:

- ``three-phase``: [`pmsmjax.presets.book_drive`][pmsmjax.presets.three_phase.book_drive] (dq machine, SVPWM,
  averaged bridge, PI FOC);
- ``six-phase <scheme>``:
  `pmsmjax.presets.six_phase.six_phase_drive` with each control
  scheme (dq + z1-z2 machine, four-vector SVPWM, averaged bridge);
- the same two with the switching-resolved bridges (7 segments against 13 per period); the six-phase PR
  scheme against the three-phase PR drive
  ([`pmsmjax.presets.pr_drive`][pmsmjax.presets.three_phase.pr_drive]);
- a ``vmap`` batch (``--batch``, default 64 runs) of the three-phase and the six-phase VSD drive: the
  per-run cost that Monte Carlo studies and tuning pay.

The cost goal: the six-phase drive's per-period cost at most 2.5 times the three-phase one's.

    python -m benchmarks.bench_six_phase --json six_phase.json
"""

import argparse

from benchmarks.bench_core import publish
from benchmarks.multiphase_cost import REQUIRED_KEYS, format_cost_table, time_against_three_phase
from pmsmjax import presets
from pmsmjax.presets.six_phase import SIX_PHASE_CONTROLS, six_phase_drive

__all__ = ["run", "main", "format_table", "REQUIRED_KEYS"]


def six_phase_drives(three) -> dict:
    """The six-phase drives and the three-phase PR drive their PR scheme is compared with."""
    drives = {f"six-phase {name}": six_phase_drive(control=name) for name in SIX_PHASE_CONTROLS}
    drives["three-phase pr"] = presets.pr_drive()
    drives["six-phase vsd switching"] = six_phase_drive(control="vsd", bridge="switching")
    return drives


PAIRS = {
    "six-phase pr": "three-phase pr",
    "three-phase pr": "three-phase pr",
    "six-phase vsd switching": "three-phase switching",
}


def run(quick: bool = False, batch: int = 64) -> dict:
    """Time every drive on the book scenario (``quick``: 0.02 s, 1 round, batch 4; figures meaningless)."""
    return time_against_three_phase(six_phase_drives, "six-phase vsd", PAIRS, quick=quick, batch=batch)


def format_table(r: dict) -> str:
    return format_cost_table(r, "six-phase")


def main(json_path: str | None = None, quick: bool = False, batch: int = 64) -> dict:
    """Run, print the table, write JSON to ``json_path`` if given; returns the figures."""
    results = run(quick=quick, batch=batch)
    return publish(results, format_table(results), json_path)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="per-period cost of the six-phase drive vs three-phase")
    parser.add_argument("--json", help="write the figures to this JSON file")
    parser.add_argument("--batch", type=int, default=64, help="vmap batch size (default 64)")
    parser.add_argument("--quick", action="store_true", help="small sizes (smoke test; figures meaningless)")
    args = parser.parse_args()
    main(args.json, args.quick, args.batch)
