"""Hysteresis current control: switching frequency and ripple against band and sample period, and the
cost per simulated second against the PI drive.

Operating figures (float64):
[`pmsmjax.presets.hysteresis_drive`][pmsmjax.presets.three_phase.hysteresis_drive] through the book scenario
(1000 r/min step, 10 N m at 0.2 s, 0.4 s) for every band, comparator sample period and computational-delay
setting; over the loaded, settled last quarter (0.3-0.4 s): mean switching frequency (transitions per leg per
second / 2, comparable with a PWM carrier), RMS and peak of the phase-current error ``i_abc - i_abc*``.

Cost: the same scenario with [`pmsmjax.presets.book_drive`][pmsmjax.presets.three_phase.book_drive] (FOC,
SVPWM, averaged bridge, 10 kHz, 10 RK4 sub-steps) and with the hysteresis preset at 5, 10 and 20 us (1
sub-step), in float64 and float32: compile time (first call minus a steady call) and run time (best of
``reps`` interleaved rounds), as wall seconds per simulated second and relative to the PI drive in the same
dtype. ``quick=True`` shrinks the sizes for a smoke test; its figures mean nothing.
"""

import argparse
import dataclasses

import jax

from benchmarks.bench_core import compile_time, machine_info, publish, time_interleaved
from pmsmjax import presets, simulate
from pmsmjax.analysis import metrics

__all__ = ["run", "main", "format_table", "REQUIRED_KEYS"]

REQUIRED_KEYS = ("operating", "cost", "machine")


@dataclasses.dataclass(frozen=True)
class Sizes:
    duration_s: float  # book scenario length (load step at half of it)
    sample_periods_s: tuple[float, ...]
    bands_a: tuple[float, ...]
    delays: tuple[bool, ...]
    reps: int  # timed rounds after the compiling call


FULL = Sizes(0.4, (5e-6, 10e-6, 20e-6), (2.0, 1.0, 0.5, 0.25), (False, True), reps=5)
QUICK = Sizes(0.02, (10e-6,), (1.0, 0.5), (False,), reps=1)


def run(quick: bool = False) -> dict:
    """Measure (see the module docstring); returns the figures."""
    sizes = QUICK if quick else FULL
    cost = {}  # first, so that its compile times are not taken from the sweep's cache
    for dtype, x64 in (("float64", True), ("float32", False)):
        with jax.enable_x64(x64):
            cost[dtype] = _cost(sizes)
    with jax.enable_x64(True):
        operating = _operating(sizes)
    return {"duration_s": sizes.duration_s, "operating": operating, "cost": cost, "machine": machine_info()}


def _scenario(sizes: Sizes):
    return presets.book_scenario(load_time_s=sizes.duration_s / 2, duration_s=sizes.duration_s)


def _operating(sizes: Sizes) -> list[dict]:
    scenario = _scenario(sizes)
    rows = []
    for ts in sizes.sample_periods_s:
        for delay in sizes.delays:
            for band in sizes.bands_a:
                drive = presets.hysteresis_drive(band_a=band, sample_period_s=ts, computation_delay=delay)
                tr = simulate(drive, scenario)
                window = tr[int(0.75 * tr.t.shape[0]) :]
                i_ref = metrics.reference_phase_currents(window.i_dq_ref, window.theta_e_est)
                rows.append(
                    {
                        "sample_period_us": ts * 1e6,
                        "computation_delay": delay,
                        "band_a": band,
                        "switching_frequency_khz": float(
                            metrics.switching_frequency_hz(window.duties, window.t[1] - window.t[0]) / 1e3
                        ),
                        "ripple_rms_a": float(metrics.current_error_rms_a(window.i_abc, i_ref)),
                        "ripple_peak_a": float(metrics.current_error_peak_a(window.i_abc, i_ref)),
                        "final_speed_rpm": float(tr.speed_rpm[-1]),
                    }
                )
    return rows


def _cost(sizes: Sizes) -> dict:
    scenario = _scenario(sizes)
    drives = {"pi_10khz": presets.book_drive()}
    for ts in sizes.sample_periods_s:
        drives[f"hysteresis_{ts * 1e6:g}us"] = presets.hysteresis_drive(sample_period_s=ts)
    calls = {name: (lambda d=d: simulate(d, scenario)) for name, d in drives.items()}
    first, best = time_interleaved(calls, sizes.reps)
    return {
        name: {
            "periods": round(sizes.duration_s / d.Ts),
            "n_substeps": d.n_substeps,
            "run_s": best[name],
            "compile_s": compile_time(first[name], best[name]),
            "wall_s_per_simulated_s": best[name] / sizes.duration_s,
            "relative_to_pi": best[name] / best["pi_10khz"],
            "us_per_period": 1e6 * best[name] / round(sizes.duration_s / d.Ts),
        }
        for name, d in drives.items()
    }


def format_table(r: dict) -> str:
    lines = [
        f"hysteresis drive, book scenario ({r['duration_s']:g} s), loaded window (last quarter), float64",
        f"{'Ts us':>6s} {'delay':>6s} {'band A':>7s} {'f_sw kHz':>9s} {'RMS err A':>10s} {'peak err A':>11s}",
    ]
    for row in r["operating"]:
        lines.append(
            f"{row['sample_period_us']:6g} {str(row['computation_delay']):>6s} {row['band_a']:7.2f} "
            f"{row['switching_frequency_khz']:9.2f} {row['ripple_rms_a']:10.3f} {row['ripple_peak_a']:11.3f}"
        )
    header = ("periods", 8), ("run ms", 8), ("compile s", 10), ("s/sim s", 8), ("x PI", 6), ("us/period", 10)
    lines.append(f"{'cost':24s} " + " ".join(f"{h:>{w}s}" for h, w in header))
    for dtype, variants in r["cost"].items():
        for name, v in variants.items():
            lines.append(
                f"{dtype + ' ' + name:24s} {v['periods']:8d} {v['run_s'] * 1e3:8.1f} {v['compile_s']:10.2f} "
                f"{v['wall_s_per_simulated_s']:8.3f} {v['relative_to_pi']:6.2f} {v['us_per_period']:10.2f}"
            )
    m = r["machine"]
    lines.append(f"machine: {m['cpu']}, {m['cpu_count']} cores, jax {m['jax']}")
    return "\n".join(lines)


def main(json_path: str | None = None, quick: bool = False) -> dict:
    """Run, print the table, write JSON to ``json_path`` if given; returns the figures."""
    results = run(quick=quick)
    return publish(results, format_table(results), json_path)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="hysteresis current control: band, sampling, cost")
    parser.add_argument("--json", help="write the figures to this JSON file")
    parser.add_argument("--quick", action="store_true", help="small sizes (smoke test; figures meaningless)")
    args = parser.parse_args()
    main(args.json, args.quick)
