"""Gains tuned over the winding-temperature range against nominally tuned gains: does either keep its
speed ITAE within 20 % of the best achievable at every winding temperature from cold to hot?

The drive is a preset drive file made warm (``[thermal]``, ``[motor]`` temperature coefficients; its
``[tolerances]`` dropped, so temperature is the only thing that varies):
``R(T) = R (1 + 0.00393 (T - 20 degC))`` (annealed copper, IEC 60028) and
``psi_f(T) = psi_f (1 - 0.0011 (T - 20 degC))`` (sintered NdFeB, magnet makers' data sheets), so from 20 to
140 degC the plant's resistance grows by 47 % and its magnet flux (torque per ampere) drops by 13 %; the
controller's model stays at the 20 degC data, as drive firmware's does
([`pmsmjax.machines.thermal`][pmsmjax.machines.thermal]).

The winding temperature of a run is pinned by the thermal network itself: ambient and initial temperature
both at ``T``, ``R_th = 0.5 K/W``, ``C_th = 1500 J/K`` (a 750 s heating time constant), so a 0.5 s run at
the book drive's 15 A peak limit and 1.41 ohm (140 degC) heats by at most
``1.5 R i^2 t / C_th = 0.16 K``.

Gain sets, each by ``pmsmjax tune`` through `pmsmjax.cli.main` (same batches, seeds and iterations):

- ``tuned at T`` for each ``T`` of `TEMPERATURES_C` (the drive file pinned at ``T``): the best-at-``T``
  reference; ``tuned at 20 degC`` is also the **nominal** tuning (the motor data's reference temperature);
- ``robust``: ``tune --robust`` on the drive file with ``[operating] winding_temperature_c = [20, 140]``
  (each training scenario starts at a temperature drawn uniformly in the band);
- ``design rules``: the untuned gains, for scale.

Each gain set then runs the same held-out scenarios (the tune job's held-out seed, 1; scenarios the tuning
never trained on) at every ``T`` on the exact model (10 RK4 sub-steps). Reported per temperature: batch-mean
ITAE, its ratio to the lowest ITAE any tuned set reaches at that temperature, the cost (ITAE plus the
overshoot, current-limit and voltage penalties) and the scenarios over the current limit.

``python -m benchmarks.operating_range_tuning [--drive book] [--iterations 100] [--train 32] [--eval 32]
[--temperatures 20 60 100 140] [--json FILE] [--figure PNG]``
"""

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.bench_core import machine_info, publish
from pmsmjax.cli import main as pmsmjax
from pmsmjax.io.drive_files import drive_spec, preset_path, write_drive_file
from pmsmjax.io.toml_parser import read_toml

#: Winding temperatures of the study, degC: cold (the data's reference) to hot (class F insulation's
#: 155 degC minus a hot-spot margin).
TEMPERATURES_C = (20.0, 60.0, 100.0, 140.0)
#: Reference temperature of the motor data, degC.
REFERENCE_C = 20.0
#: Copper's resistance coefficient (IEC 60028) and sintered NdFeB's remanence coefficient, 1/K.
R_TEMP_COEFF_PER_K = 0.00393
PSI_F_TEMP_COEFF_PER_K = -0.0011
#: The limit of the claim: ITAE within 20 % of the best at each temperature.
RATIO_LIMIT = 1.2


def warm_drive_file(drive: str, path: Path, winding_c: float, band_c=None) -> Path:
    """Write ``drive`` (a preset name or drive file) as a warm drive file at ``path``: the winding and
    ambient at ``winding_c`` (degC), the temperature coefficients of the module docstring, no
    ``[tolerances]``; ``band_c = (low, high)`` adds ``[operating] winding_temperature_c``."""
    source = preset_path(drive) or Path(drive)
    tables = {k: dict(v) for k, v in read_toml(source, str(source)).items() if k != "tolerances"}
    tables["motor"].update(
        reference_temperature_c=REFERENCE_C,
        r_temp_coeff_per_k=R_TEMP_COEFF_PER_K,
        psi_f_temp_coeff_per_k=PSI_F_TEMP_COEFF_PER_K,
    )
    tables["thermal"] = dict(r_th_k_per_w=0.5, c_th_j_per_k=1500.0, ambient_c=winding_c, initial_c=winding_c)
    if band_c is not None:
        tables["operating"] = {"winding_temperature_c": list(band_c)}
    write_drive_file(path, tables, header=f"{drive}, warm ({winding_c:g} degC winding)")
    return path


def tune(drive_file: Path, out: Path, train: int, iterations: int, robust: bool) -> float:
    """``pmsmjax tune`` on ``drive_file`` into ``out``; returns its wall time, s."""
    argv = ["tune", "--motor", str(drive_file), "--train", str(train), "--heldout", "8"]
    argv += ["--iterations", str(iterations), "--no-progress", "--out", str(out)]
    start = time.perf_counter()
    if pmsmjax([*argv, *(["--robust"] if robust else [])]) != 0:
        raise SystemExit(f"tune {drive_file} failed")
    return time.perf_counter() - start


def evaluate_at(drive_file: Path, gains: dict, n_eval: int) -> dict:
    """``{gain set: figures}`` of every gain set (``{name: gains.toml or None}``) on ``n_eval`` held-out
    scenarios (seed 1) of the drive file, on the exact model."""
    from pmsmjax.assemble import spec_drive
    from tuning.autotune import drive_scaling
    from tuning.autotune.controls import control_tuning
    from tuning.autotune.drive_batches import drive_batches
    from tuning.autotune.job import evaluate
    from tuning.autotune.objectives import ObjectiveWeights
    from tuning.parameters import apply_gains

    spec = drive_spec(str(drive_file))
    weights = drive_scaling.scaled_weights(
        ObjectiveWeights(**control_tuning("pi", "three-phase").weights), spec
    )
    batches = drive_batches(spec)
    batch = batches.make(n_eval, 1, duration_s=batches.duration_s, kinds=("step",))
    exact = spec_drive(spec, "pi", n_substeps=10)
    out = {}
    for name, path in gains.items():
        s = evaluate(exact if path is None else apply_gains(exact, str(path)), batch, weights)["summary"]
        out[name] = {
            "itae": s["itae"],
            "cost": s["cost"],
            "max_peak_current_a": s["max_peak_current_a"],
            "scenarios_over_current_limit": s["scenarios_over_current_limit"],
            "max_overshoot_pct": s["max_overshoot_pct"],
        }
    return out


def run(
    drive: str, iterations: int, train: int, n_eval: int, folder: Path, temperatures_c=TEMPERATURES_C
) -> dict:
    """Tune every gain set of the module docstring at ``temperatures_c`` (degC; the first is the
    reference, the band runs from the first to the last) and evaluate each at each temperature."""
    temperatures_c = tuple(float(t) for t in temperatures_c)
    if temperatures_c[0] != REFERENCE_C:
        raise ValueError(
            f"the first temperature must be the reference {REFERENCE_C} degC, got {temperatures_c}"
        )
    band = (temperatures_c[0], temperatures_c[-1])
    files = {t: warm_drive_file(drive, folder / f"warm_{t:g}C.toml", t) for t in temperatures_c}
    robust_file = warm_drive_file(drive, folder / "warm_band.toml", REFERENCE_C, band)
    seconds, gains = {}, {}
    for t, f in files.items():
        name = f"tuned at {t:g} degC"
        seconds[f"tune {name}"] = tune(f, folder / f"tune_{t:g}", train, iterations, robust=False)
        gains[name] = folder / f"tune_{t:g}" / "gains.toml"
    seconds["tune robust"] = tune(robust_file, folder / "tune_robust", train, iterations, robust=True)
    gains["robust"] = folder / "tune_robust" / "gains.toml"
    gains["design rules"] = None
    start = time.perf_counter()
    table = {f"{t:g}": evaluate_at(f, gains, n_eval) for t, f in files.items()}
    seconds["evaluation"] = time.perf_counter() - start
    limit_a = float(drive_spec(str(files[temperatures_c[0]])).ratings["max_current_a"])
    tuned = [n for n in gains if n != "design rules"]
    for row in table.values():
        best = min(row[n]["itae"] for n in tuned)
        within = [n for n in tuned if row[n]["scenarios_over_current_limit"] == 0]
        best_within = min(row[n]["itae"] for n in within) if within else float("nan")
        best_cost = min(row[n]["cost"] for n in tuned)
        for g in row.values():
            g["itae_ratio"] = g["itae"] / best
            g["itae_ratio_within_limit"] = g["itae"] / best_within
            g["cost_ratio"] = g["cost"] / best_cost
    nominal = f"tuned at {REFERENCE_C:g} degC"

    def worst(key):
        return {n: max(row[n][key] for row in table.values()) for n in gains}

    return {
        "drive": drive,
        "temperatures_c": list(temperatures_c),
        "band_c": list(band),
        "r_temp_coeff_per_k": R_TEMP_COEFF_PER_K,
        "psi_f_temp_coeff_per_k": PSI_F_TEMP_COEFF_PER_K,
        "current_limit_a": limit_a,
        "iterations": iterations,
        "train": train,
        "eval_scenarios": n_eval,
        "nominal": nominal,
        "results": table,
        "worst_itae_ratio": worst("itae_ratio"),
        "worst_itae_ratio_within_limit": worst("itae_ratio_within_limit"),
        "worst_cost_ratio": worst("cost_ratio"),
        "itae_within_ratio_limit_everywhere": {
            n: bool(r <= RATIO_LIMIT) for n, r in worst("itae_ratio").items()
        },
        "within_current_limit_everywhere": {
            n: all(row[n]["scenarios_over_current_limit"] == 0 for row in table.values()) for n in gains
        },
        "gains": {n: None if p is None else read_toml(p, str(p)) for n, p in gains.items()},
        "seconds": seconds,
        "machine": machine_info(),
    }


def format_table(r: dict) -> str:
    names = list(r["worst_itae_ratio"])
    temps = list(r["results"])

    def block(title, cell, last):
        rows = [f"  {title}"]
        rows.append(f"  {'gains':18s}" + "".join(f"{t + ' degC':>20s}" for t in temps) + f"{last:>13s}")
        for n in names:
            cells = "".join(f"{cell(r['results'][t][n]):>20s}" for t in temps)
            rows.append(f"  {n:18s}{cells}{_worst(r, n, last):>13s}")
        return rows

    rows = [
        f"{r['drive']}, warm: {r['eval_scenarios']} held-out scenarios, {r['train']} training scenarios, "
        f"{r['iterations']} iterations; nominal = {r['nominal']}; current limit {r['current_limit_a']:g} A"
    ]
    rows += block(
        "batch-mean speed ITAE (rad s) (ratio to the lowest of any tuned set at that temperature)",
        lambda g: f"{g['itae']:.4g} ({g['itae_ratio']:.3f})",
        "worst ratio",
    )
    rows += block(
        "scenarios over the current limit, peak current (A), ITAE ratio to the best set within the limit",
        lambda g: (
            f"{g['scenarios_over_current_limit']:d}, {g['max_peak_current_a']:.2f}, "
            f"{g['itae_ratio_within_limit']:.3f}"
        ),
        "worst ratio ",
    )
    rows += block(
        "tuning cost (ITAE + penalties) (ratio to the lowest of any tuned set)",
        lambda g: f"{g['cost']:.4g} ({g['cost_ratio']:.2f})",
        "worst cost",
    )
    rows += [f"  {k:24s} {v:6.1f} s" for k, v in r["seconds"].items()]
    return "\n".join(rows)


def _worst(r: dict, name: str, column: str) -> str:
    key = {"worst ratio": "worst_itae_ratio", "worst ratio ": "worst_itae_ratio_within_limit"}
    return f"{r[key.get(column, 'worst_cost_ratio')][name]:.3f}"


def figure(r: dict, path: str) -> None:
    """Left: ITAE ratio against winding temperature, one line per gain set, the 1.2 limit drawn, a red
    ring where the set drives a scenario over the current limit. Right: the sets' peak current."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pmsmjax.plotting.traces import save_figure

    temps = np.asarray(r["temperatures_c"])
    names = [n for n in r["worst_itae_ratio"] if n != "design rules"]  # 12x the best: off the scale
    fig, (ax, ax_i) = plt.subplots(1, 2, figsize=(11.5, 4.2))
    for n in names:
        rows = [r["results"][f"{t:g}"][n] for t in temps]
        style = dict(color="k", lw=2.2, marker="s") if n == "robust" else dict(marker="o")
        label = f"{n} (nominal)" if n == r["nominal"] else ("robust over the range" if n == "robust" else n)
        (line,) = ax.plot(temps, [g["itae_ratio"] for g in rows], **style, label=label)
        over = [g["scenarios_over_current_limit"] > 0 for g in rows]
        ax.plot(temps[over], np.asarray([g["itae_ratio"] for g in rows])[over], "o", ms=13, mfc="none",
                mec="tab:red", mew=1.5)  # fmt: skip
        ax_i.plot(temps, [g["max_peak_current_a"] for g in rows], **{**style, "color": line.get_color()})
    ax.plot(
        [], [], "o", ms=11, mfc="none", mec="tab:red", mew=1.5, label="some scenarios over the current limit"
    )
    ax.axhline(RATIO_LIMIT, color="tab:red", ls=":", lw=1.5, label="1.2 x best")
    ax.set(
        xlabel="winding temperature / degC",
        ylabel="ITAE / lowest tuned ITAE at that temperature",
        title="Speed ITAE over the winding-temperature range",
        xticks=temps,
        ylim=(0.95, max(1.3, 1.05 * max(r["worst_itae_ratio"][n] for n in names))),
    )
    ax_i.axhline(r["current_limit_a"], color="tab:red", ls=":", lw=1.5)
    ax_i.text(temps[0], r["current_limit_a"], " current limit", color="tab:red", va="bottom", fontsize=8)
    ax_i.set(
        xlabel="winding temperature / degC",
        ylabel="largest peak current of the batch / A",
        title="Peak current",
        xticks=temps,
    )
    for a in (ax, ax_i):
        a.grid(alpha=0.3)
    fig.legend(*ax.get_legend_handles_labels(), loc="lower center", fontsize=8, ncol=4)  # below the data
    band = "-".join(f"{t:g}" for t in r["band_c"])
    fig.suptitle(f"{r['drive']} drive, warm: gains tuned at one temperature or over {band} degC", fontsize=10)
    fig.tight_layout(rect=(0, 0.1, 1, 1))
    save_figure(fig, path)


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--drive", default="book")
    parser.add_argument("--iterations", type=int, default=100)
    parser.add_argument("--train", type=int, default=32)
    parser.add_argument("--eval", type=int, default=32, help="held-out scenarios per temperature")
    parser.add_argument(
        "--temperatures", type=float, nargs="+", default=TEMPERATURES_C, help="winding temperatures, degC"
    )
    parser.add_argument("--json", default=None)
    parser.add_argument("--figure", default=None)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as folder:
        results = run(args.drive, args.iterations, args.train, args.eval, Path(folder), args.temperatures)
    published = publish(results, format_table(results), args.json)
    if args.figure:
        figure(results, args.figure)
    return published


if __name__ == "__main__":
    main()
