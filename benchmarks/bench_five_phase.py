"""Per-period cost of the five-phase drive against the three-phase book drive, in one run (the book, ch. 10).

Every drive simulates the same book scenario (1000 r/min, 10 N m at 0.2 s, 0.4 s; float32 unless x64 is
enabled, as the command line runs), timed interleaved
([`benchmarks.bench_core.time_interleaved`][pmsmjax.jobs.bench.time_interleaved]) so the ratios
hold under a varying machine load:

- ``three-phase``: [`pmsmjax.presets.book_drive`][pmsmjax.presets.three_phase.book_drive] (dq machine, SVPWM,
  averaged bridge, PI FOC);
- ``five-phase <scheme>``:
  `pmsmjax.presets.five_phase.five_phase_drive` with each
  control scheme (dq + x-y machine integrated split, near-four-vector SVPWM, averaged bridge);
  ``five-phase vsd carrier``: min-max carrier PWM instead;
- ``five-phase vsd third-harmonic``: the preset with ``psi_f3 = 0.1 psi_f`` (the angle then drives x-y:
  the dq model integrates the whole state by RK4, no split);
- the switching-resolved bridges (7 segments per period for three legs, 11 for five);
- a ``vmap`` batch (``--batch``, default 64 runs) of the three-phase and the five-phase VSD drive.

    python -m benchmarks.bench_five_phase --json five_phase.json
"""

import argparse

from benchmarks.bench_core import publish
from benchmarks.multiphase_cost import REQUIRED_KEYS, format_cost_table, time_against_three_phase
from pmsmjax.presets.five_phase import FIVE_PHASE_CONTROLS, five_phase_drive, five_phase_motor

__all__ = ["run", "main", "format_table", "REQUIRED_KEYS"]


def five_phase_drives(three) -> dict:
    """The five-phase drives: each scheme, carrier PWM, third-harmonic back-EMF, switching bridge."""
    drives = {f"five-phase {name}": five_phase_drive(control=name) for name in FIVE_PHASE_CONTROLS}
    drives["five-phase vsd carrier"] = five_phase_drive(pwm="carrier")
    drives["five-phase vsd third-harmonic"] = five_phase_drive(
        five_phase_motor(third_harmonic=0.1), pwm="carrier"
    )
    drives["five-phase vsd switching"] = five_phase_drive(bridge="switching")
    return drives


PAIRS = {"five-phase vsd switching": "three-phase switching"}


def run(quick: bool = False, batch: int = 64) -> dict:
    """Time every drive on the book scenario (``quick``: 0.02 s, 1 round, batch 4; figures meaningless)."""
    return time_against_three_phase(five_phase_drives, "five-phase vsd", PAIRS, quick=quick, batch=batch)


def format_table(r: dict) -> str:
    return format_cost_table(r, "five-phase")


def main(json_path: str | None = None, quick: bool = False, batch: int = 64) -> dict:
    """Run, print the table, write JSON to ``json_path`` if given; returns the figures."""
    results = run(quick=quick, batch=batch)
    return publish(results, format_table(results), json_path)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="per-period cost of the five-phase drive vs three-phase")
    parser.add_argument("--json", help="write the figures to this JSON file")
    parser.add_argument("--batch", type=int, default=64, help="vmap batch size (default 64)")
    parser.add_argument("--quick", action="store_true", help="small sizes (smoke test; figures meaningless)")
    args = parser.parse_args()
    main(args.json, args.quick, args.batch)
