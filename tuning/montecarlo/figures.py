"""Figures of a Monte Carlo study: metric histograms, fan charts of speed and current, a tornado chart."""

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from pmsmjax.plotting.traces import save_figure
from tuning.montecarlo.kernel import METRICS, UNITS

#: Percentile bands of the fan chart, outermost first.
BANDS = ((5, 95), (25, 75))


def histogram_figure(results: dict, summary: dict):
    """One histogram per metric over the finite runs, with the median and the 95th percentile marked."""
    fig, axes = plt.subplots(2, 3, figsize=(12, 6.5))
    finite = results["finite"] > 0.5
    for ax, m in zip(axes.flat, METRICS, strict=True):
        v = results[m][finite]
        v = np.abs(v) if m == "final_error_rpm" else v
        v = v[np.isfinite(v)]
        # About sqrt(n) bins (10 to 40): 40 bins of 64 runs is mostly empty bins and single counts.
        ax.hist(v, bins=int(np.clip(np.sqrt(max(v.size, 1)), 10, 40)), color="C0", alpha=0.8)
        stats = summary["metrics"][m]
        for key, style in (("p50", "k-"), ("p95", "r--")):
            if stats.get(key) is not None:
                ax.axvline(stats[key], color=style[0], ls=style[1:], lw=1.2, label=key)
        label = "|final error|" if m == "final_error_rpm" else m
        ax.set(xlabel=f"{label} / {UNITS[m]}", ylabel="runs")
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
    fig.suptitle(f"Monte Carlo: {summary['n_runs']} runs")
    fig.tight_layout()
    return fig


def fan_chart_figure(results: dict, t: np.ndarray):
    """Speed and q-axis current against time: median and percentile bands over the finite runs."""
    fig, axes = plt.subplots(2, 1, figsize=(8, 6.5), sharex=True)
    finite = results["finite"] > 0.5
    for ax, (key, label) in zip(axes, (("speed_rpm", "n / (r/min)"), ("i_q_a", "$i_q$ / A")), strict=True):
        x = results[key][finite]
        if x.shape[0]:
            # Every band and the median from one partition of each time column (a million runs: one
            # pass over the record instead of five).
            levels = [p for band in BANDS for p in band] + [50]
            q = dict(zip(levels, np.percentile(x, levels, axis=0), strict=True))
            for (lo, hi), alpha in zip(BANDS, (0.25, 0.45), strict=True):
                ax.fill_between(t, q[lo], q[hi], alpha=alpha, color="C0", label=f"{lo}-{hi} %")
            ax.plot(t, q[50], "k-", lw=1.2, label="median")
        ax.set(ylabel=label)
        ax.grid(alpha=0.3)
        ax.legend(loc="lower right")
    axes[0].set_title("Speed and q-axis current over the population")
    axes[1].set_xlabel("t / s")
    fig.tight_layout()
    return fig


def tornado_figure(summary: dict):
    """Per metric, the mean change for each parameter moved by one tolerance half-width (from AD)."""
    sens = summary["sensitivities"]["per_tolerance"]
    fig, axes = plt.subplots(2, 3, figsize=(13, 6.5))
    for ax, m in zip(axes.flat, METRICS, strict=True):
        row = {p: v for p, v in sens[m].items() if v is not None}
        order = sorted(row, key=lambda p: abs(row[p]))
        values = [row[p] for p in order]
        bars = ax.barh(order, values, color=["C3" if v > 0 else "C0" for v in values])
        # Every bar carries its value: bars a hundred times shorter than the longest are invisible.
        if any(values):
            ax.bar_label(bars, labels=[f"{v:+.2g}" for v in values], fontsize=7, padding=2)
        span = max((abs(v) for v in values), default=0.0)
        if span > 0:
            ax.set_xlim(min(0.0, min(values)) - 0.35 * span, max(0.0, max(values)) + 0.35 * span)
        ax.axvline(0.0, color="k", lw=0.8)
        if not any(row.values()):
            # Settling time is piecewise constant in the parameters: AD sees a zero derivative.
            ax.text(
                0.5,
                0.5,
                "zero derivative almost everywhere:\nsee the Spearman ranks",
                ha="center",
                va="center",
                transform=ax.transAxes,
                fontsize=9,
                color="0.3",
            )
        ax.set(title=m, xlabel=f"change / {UNITS[m]}")
        ax.grid(alpha=0.3, axis="x")
    fig.suptitle(
        "Sensitivities (AD, population mean): metric change per +1 tolerance of each parameter "
        "(red: the metric grows, blue: it shrinks)"
    )
    fig.tight_layout()
    return fig


def save_study_figures(results: dict, summary: dict, t: np.ndarray, out_dir) -> list[Path]:
    """Write histograms.png, fan_chart.png and (with sensitivities) tornado.png; returns the paths."""
    out_dir = Path(out_dir)
    paths = [
        save_figure(histogram_figure(results, summary), out_dir / "histograms.png"),
        save_figure(fan_chart_figure(results, t), out_dir / "fan_chart.png"),
    ]
    if summary.get("sensitivities"):
        paths.append(save_figure(tornado_figure(summary), out_dir / "tornado.png"))
    return paths
