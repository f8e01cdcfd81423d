"""Switching-segment bridge against the brute-force carrier reference: speed and accuracy, one run.

The book drive (closed loop, FOC, SVPWM, 10 kHz) at steady state (1000 r/min, 10 N m, reached with the
averaged bridge) simulates the same stretch of time with:

- ``averaged``: the averaged bridge (10 RK4 sub-steps per period; no ripple), for scale;
- ``segments``: [`pmsmjax.inverters.SwitchingBridge`][pmsmjax.inverters.switching.SwitchingBridge] (7
  segments, 1 RK4 step each);
- ``segments_deadtime``: the same with a 2 us dead time (13 segments);
- ``carrier2000`` / ``carrier4000``: `benchmarks.pwm_reference.CarrierReferenceBridge` with 2000 /
  4000 RK4 steps per period (50 / 25 ns), the fine-step carrier comparison.

Figures: compile time (first call minus a steady call), run time (best of ``reps`` interleaved rounds,
``block_until_ready``), simulated seconds per wall second, the speed-up of the segment model over each
reference per simulated second, and the largest phase-current difference between the segment model and
the references over the window (uniform samples, 20 per period) in % of the ripple peak-to-peak. float64
(accuracy is compared). ``quick=True`` shrinks the sizes for a smoke test; its timings mean nothing.
"""

import argparse
import dataclasses

import equinox as eqx
import jax
import numpy as np

from benchmarks.bench_core import compile_time, machine_info, publish, time_interleaved
from benchmarks.pwm_reference import CarrierReferenceBridge, dense_phase_currents
from pmsmjax import Profile, Scenario, simulate
from pmsmjax.inverters import SwitchingBridge
from pmsmjax.jobs.pwm_comparison import CompareSettings, steady_state
from pmsmjax.presets.book_constants import BOOK_DC_LINK
from pmsmjax.presets.three_phase import book_drive

__all__ = ["run", "main", "format_table", "REQUIRED_KEYS"]

REQUIRED_KEYS = ("variants", "speedup_vs_carrier4000", "speedup_vs_carrier2000", "accuracy", "machine")


@dataclasses.dataclass(frozen=True)
class Sizes:
    periods: int  # PWM periods simulated by each variant (150 = one fundamental period)
    reps: int  # timed rounds after the compiling call
    fine: tuple[int, ...]  # RK4 steps per period of the references


FULL = Sizes(periods=300, reps=5, fine=(2000, 4000))
QUICK = Sizes(periods=20, reps=1, fine=(200, 400))


def run(quick: bool = False) -> dict:
    """Measure every variant; returns the figures (see the module docstring)."""
    with jax.enable_x64(True):
        return _run(QUICK if quick else FULL)


def _run(sizes: Sizes) -> dict:
    base = book_drive()
    start = steady_state(base, CompareSettings())
    scenario = Scenario(
        duration_s=sizes.periods * base.Ts,
        speed_ref=Profile.constant(1000.0 * np.pi / 30.0),
        load_torque=Profile.constant(10.0),
    )
    bridges = {
        "averaged": base.bridge,
        "segments": SwitchingBridge(BOOK_DC_LINK),
        "segments_deadtime": SwitchingBridge(BOOK_DC_LINK, dead_time=2e-6),
    }
    for n in sizes.fine:
        bridges[f"carrier{n}"] = CarrierReferenceBridge(BOOK_DC_LINK, n_fine=n)
    drives = {name: eqx.tree_at(lambda d: d.bridge, base, b) for name, b in bridges.items()}
    calls = {name: (lambda d=d: simulate(d, scenario, initial_state=start)) for name, d in drives.items()}
    first, best = time_interleaved(calls, sizes.reps)
    simulated_s = sizes.periods * base.Ts
    variants = {
        name: {
            "run_s": best[name],
            "compile_s": compile_time(first[name], best[name]),
            "simulated_s_per_wall_s": simulated_s / best[name],
            "periods_per_s": sizes.periods / best[name],
        }
        for name in drives
    }
    fine_lo, fine_hi = (f"carrier{n}" for n in sizes.fine)
    currents = {
        name: dense_phase_currents(drives[name], calls[name](), 20) for name in ("segments", fine_lo, fine_hi)
    }
    ripple = np.ptp(currents[fine_hi].reshape(sizes.periods, 20, 3), axis=1).max()
    accuracy = {
        "ripple_peak_to_peak_a": float(ripple),
        **{
            f"max_current_diff_vs_{name}_pct_of_ripple": float(
                100 * np.abs(currents["segments"] - currents[name]).max() / ripple
            )
            for name in (fine_lo, fine_hi)
        },
    }
    return {
        "n_periods": sizes.periods,
        "simulated_s": simulated_s,
        "dtype": "float64",
        "variants": variants,
        "speedup_vs_carrier4000": best[fine_hi] / best["segments"],
        "speedup_vs_carrier2000": best[fine_lo] / best["segments"],
        "speedup_deadtime_vs_carrier4000": best[fine_hi] / best["segments_deadtime"],
        "accuracy": accuracy,
        "machine": machine_info(),
    }


def format_table(r: dict) -> str:
    lines = [
        f"{r['n_periods']} PWM periods ({r['simulated_s'] * 1e3:g} ms) of the book drive at steady state, "
        f"{r['dtype']}",
        f"{'variant':20s} {'run ms':>9s} {'compile s':>10s} {'sim s / wall s':>15s}",
    ]
    for name, v in r["variants"].items():
        lines.append(
            f"{name:20s} {v['run_s'] * 1e3:9.2f} {v['compile_s']:10.2f} {v['simulated_s_per_wall_s']:15.3f}"
        )
    a = r["accuracy"]
    lines += [
        f"segments faster than carrier (h = Ts/4000): {r['speedup_vs_carrier4000']:.0f}x, "
        f"(h = Ts/2000): {r['speedup_vs_carrier2000']:.0f}x; with dead time vs h = Ts/4000: "
        f"{r['speedup_deadtime_vs_carrier4000']:.0f}x",
        f"ripple p-p {a['ripple_peak_to_peak_a']:.3f} A; "
        + ", ".join(
            f"{k.removeprefix('max_current_diff_vs_')} {v:.2f}" for k, v in a.items() if k.startswith("max_")
        ),
        f"machine: {r['machine']['cpu']}, {r['machine']['cpu_count']} cores, jax {r['machine']['jax']}",
    ]
    return "\n".join(lines)


def main(json_path: str | None = None, quick: bool = False) -> dict:
    """Run, print the table, write JSON to ``json_path`` if given; returns the figures."""
    results = run(quick=quick)
    return publish(results, format_table(results), json_path)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="switching-segment bridge vs carrier reference")
    parser.add_argument("--json", help="write the figures to this JSON file")
    parser.add_argument("--quick", action="store_true", help="small sizes (smoke test; timings meaningless)")
    args = parser.parse_args()
    main(args.json, args.quick)
