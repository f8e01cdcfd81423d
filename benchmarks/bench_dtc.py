"""Direct torque control (the book, ch. 4): ripple against bands and sample period, equal switching
frequency, and the cost per simulated second against the FOC drive.

Operating figures (float64), from
[`pmsmjax.jobs.control_comparison.run_control`][pmsmjax.jobs.control_comparison.run_control] (the book
scenario: 1000 r/min step, 10 N m at 0.2 s, 0.4 s; the last two electrical periods, sampled 32 times per 100
us):

- switching-table DTC ([`pmsmjax.presets.dtc_drive`][pmsmjax.presets.three_phase.dtc_drive]) at each sample
  period, with the book bands (1 N m, 10 mWb) times each factor: mean switching frequency, torque ripple (RMS
  and peak-to-peak about the window mean), flux-magnitude ripple, current THD;
- the same with the bands matched to the 10 kHz of the SVPWM drives
  ([`pmsmjax.jobs.equal_switching.match_switching_frequency`][pmsmjax.jobs.equal_switching.match_switching_frequency]),
  where the sample period allows it;
- sliding-mode DTC ([`pmsmjax.presets.smc_dtc_drive`][pmsmjax.presets.three_phase.smc_dtc_drive], saturation
  and sign switching) and the FOC drive, both with SVPWM at 10 kHz on the switching-resolved bridge.

Cost: the book scenario with the FOC drive (SVPWM, averaged bridge, 10 kHz, 10 RK4 sub-steps), the SMC-DTC
drive (same modulation and sub-steps) and the table DTC at 25 us (1 sub-step), in float64 and float32:
compile time (first call minus a steady call) and run time (best of ``reps`` interleaved rounds), as wall
seconds per simulated second and relative to the FOC drive in the same dtype. ``quick=True`` shrinks the
sizes for a smoke test; its figures mean nothing.
"""

import argparse
import dataclasses

import equinox as eqx
import jax

from benchmarks.bench_core import compile_time, machine_info, publish, time_interleaved
from pmsmjax import presets, simulate
from pmsmjax.inverters.switching import SwitchingBridge
from pmsmjax.jobs.control_comparison import ControllerCompareSettings, run_control, window_periods
from pmsmjax.jobs.equal_switching import match_switching_frequency, scale_bands
from pmsmjax.presets.control_methods import control_drive

__all__ = ["run", "main", "format_table", "REQUIRED_KEYS"]

REQUIRED_KEYS = ("operating", "cost", "machine")
KEYS = (
    "switching_frequency_hz",
    "torque_ripple_nm",
    "torque_ripple_pp_nm",
    "flux_ripple_wb",
    "current_thd_pct",
    "final_speed_rpm",
)


@dataclasses.dataclass(frozen=True)
class Sizes:
    duration_s: float  # book scenario length (load step at half of it)
    sample_periods_s: tuple[float, ...]
    band_factors: tuple[float, ...]
    match_hz: float
    reps: int  # timed rounds after the compiling call


FULL = Sizes(0.4, (20e-6, 25e-6, 50e-6), (2.0, 1.0, 0.5, 0.25), 1e4, reps=5)
QUICK = Sizes(0.06, (25e-6,), (1.0,), 1e4, reps=1)


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


def _settings(sizes: Sizes) -> ControllerCompareSettings:
    return ControllerCompareSettings(load_time_s=sizes.duration_s / 2, duration_s=sizes.duration_s)


def _row(label: str, entry: dict, **extra) -> dict:
    return {"drive": label, **extra, **{k: entry[k] for k in KEYS}}


def _operating(sizes: Sizes) -> list[dict]:
    settings = _settings(sizes)
    scenario = presets.book_scenario(load_time_s=settings.load_time_s, duration_s=settings.duration_s)
    rows = []
    for ts in sizes.sample_periods_s:
        base = presets.dtc_drive(sample_period_s=ts)
        n_window = window_periods(base, settings)
        for factor in sizes.band_factors:
            drive = scale_bands(base, factor)
            entry = run_control("dtc", drive, settings)["entry"]
            rows.append(_row("dtc", entry, sample_period_us=ts * 1e6, band_factor=factor))
        if sizes.match_hz < 0.5 / ts:
            match = match_switching_frequency(base, scenario, sizes.match_hz, n_window)
            entry = run_control("dtc", match["drive"], settings)["entry"]
            rows.append(_row("dtc (matched)", entry, sample_period_us=ts * 1e6, band_factor=match["factor"]))
    for label, name, options in (
        ("smc-dtc saturation", "smc-dtc", {}),
        ("smc-dtc sign", "smc-dtc", {"switching": "sign"}),
        ("pi (FOC)", "pi", {}),
    ):
        drive = _on_bridge(control_drive(name, **options), settings.bridge)
        entry = run_control(name, drive, settings)["entry"]
        rows.append(_row(label, entry, sample_period_us=drive.Ts * 1e6, band_factor=None))
    return rows


def _on_bridge(drive, bridge: str):
    """``drive`` on the switching-resolved bridge when it commands a voltage and ``bridge == "switching"``
    (as [`pmsmjax.jobs.control_comparison.compared_drive`][pmsmjax.jobs.control_comparison.compared_drive]
    does)."""
    if bridge == "switching" and drive.controller.command_kind == "voltage":
        drive = eqx.tree_at(lambda d: d.bridge, drive, SwitchingBridge(drive.bridge.u_dc))
    return drive


def _cost(sizes: Sizes) -> dict:
    scenario = presets.book_scenario(load_time_s=sizes.duration_s / 2, duration_s=sizes.duration_s)
    drives = {
        "foc_10khz": presets.book_drive(),
        "smc_dtc_10khz": presets.smc_dtc_drive(),
        "dtc_25us": presets.dtc_drive(sample_period_s=25e-6),
    }
    calls = {name: (lambda d=d: simulate(d, scenario)) for name, d in drives.items()}
    first, best = time_interleaved(calls, sizes.reps)
    return {
        name: {
            "periods": round(sizes.duration_s / d.Ts),
            "n_substeps": d.n_substeps,
            "run_s": best[name],
            "compile_s": compile_time(first[name], best[name]),
            "wall_s_per_simulated_s": best[name] / sizes.duration_s,
            "relative_to_foc": best[name] / best["foc_10khz"],
            "us_per_period": 1e6 * best[name] / round(sizes.duration_s / d.Ts),
        }
        for name, d in drives.items()
    }


def format_table(r: dict) -> str:
    lines = [
        f"DTC, book scenario ({r['duration_s']:g} s), last two electrical periods under load, float64",
        f"{'drive':20s} {'Ts us':>6s} {'bands x':>8s} {'f_sw kHz':>9s} {'T RMS':>7s} {'T p-p':>7s} "
        f"{'psi RMS mWb':>12s} {'THD %':>6s}",
    ]
    for row in r["operating"]:
        factor = "-" if row["band_factor"] is None else f"{row['band_factor']:.3f}"
        lines.append(
            f"{row['drive']:20s} {row['sample_period_us']:6g} {factor:>8s} "
            f"{row['switching_frequency_hz'] / 1e3:9.2f} {row['torque_ripple_nm']:7.3f} "
            f"{row['torque_ripple_pp_nm']:7.3f} {1e3 * row['flux_ripple_wb']:12.2f} "
            f"{row['current_thd_pct']:6.2f}"
        )
    header = ("periods", 8), ("run ms", 8), ("compile s", 10), ("s/sim s", 8), ("x FOC", 6), ("us/period", 10)
    lines.append(f"{'cost':24s} " + " ".join(f"{h:>{w}s}" for h, w in header))
    for dtype, variants in r["cost"].items():
        for name, v in variants.items():
            lines.append(
                f"{dtype + ' ' + name:24s} {v['periods']:8d} {v['run_s'] * 1e3:8.1f} {v['compile_s']:10.2f} "
                f"{v['wall_s_per_simulated_s']:8.3f} {v['relative_to_foc']:6.2f} {v['us_per_period']:10.2f}"
            )
    m = r["machine"]
    lines.append(f"machine: {m['cpu']}, {m['cpu_count']} cores, jax {m['jax']}")
    return "\n".join(lines)


def main(json_path: str | None = None, quick: bool = False) -> dict:
    """Run, print the table, write JSON to ``json_path`` if given; returns the figures."""
    results = run(quick=quick)
    return publish(results, format_table(results), json_path)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="direct torque control: bands, sampling, equal f_sw, cost")
    parser.add_argument("--json", help="write the figures to this JSON file")
    parser.add_argument("--quick", action="store_true", help="small sizes (smoke test; figures meaningless)")
    args = parser.parse_args()
    main(args.json, args.quick)
