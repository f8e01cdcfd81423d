"""Figures in the style of the book's result plots (speed, currents, torque, voltages against time)."""

from pathlib import Path

# No backend is forced: matplotlib falls back to Agg without a display (the CLI), and notebooks keep
# their inline backend.
import matplotlib.pyplot as plt
import numpy as np

from .logs import atomic_write
from .trace import Trace
from .units import rad_s_to_rpm


def save_figure(fig, path: Path) -> Path:
    """Write a figure as PNG atomically (:func:`pmsmjax.logs.atomic_write`) and close it."""
    try:
        return atomic_write(path, lambda f: fig.savefig(f, format="png", dpi=120, bbox_inches="tight"))
    finally:
        plt.close(fig)


def _panel(ax, trace: Trace, title: str, ylabel: str, lines, legend_loc: str = "upper right"):
    """Draw ``lines`` = [(values (N,), matplotlib format, label), ...] against time on ``ax``."""
    ax = ax or plt.subplots(figsize=(7, 3))[1]
    t = np.asarray(trace.t)
    for values, fmt, label in lines:
        ax.plot(t, np.asarray(values), fmt, lw=1.2 if fmt == "-" else 0.9, label=label)
    ax.set(xlabel="t / s", ylabel=ylabel, title=title)
    ax.grid(alpha=0.3)
    ax.legend(loc=legend_loc)
    return ax


def plot_speed(trace: Trace, ax=None):
    """Speed and its reference, r/min."""
    lines = [(rad_s_to_rpm(trace.speed_ref), "k--", "reference"), (trace.speed_rpm, "-", "speed")]
    return _panel(ax, trace, "Speed", "n / (r/min)", lines, "lower right")


def plot_dq_currents(trace: Trace, ax=None):
    """dq currents and the q reference, A."""
    lines = [(trace.i_dq[:, 0], "-", "$i_d$"), (trace.i_dq[:, 1], "-", "$i_q$")]
    lines.append((trace.i_dq_ref[:, 1], "k--", "$i_q^*$"))
    return _panel(ax, trace, "dq currents", "i / A", lines)


def plot_phase_currents(trace: Trace, ax=None):
    """Phase currents, A."""
    lines = [(trace.i_abc[:, k], "-", f"$i_{name}$") for k, name in enumerate("abc")]
    return _panel(ax, trace, "Phase currents", "i / A", lines)


def plot_torque(trace: Trace, ax=None):
    """Electromagnetic and load torque, N m."""
    lines = [(trace.torque, "-", "$T_e$"), (trace.load_torque, "k--", "$T_L$")]
    return _panel(ax, trace, "Torque", "T / (N m)", lines)


def plot_voltages(trace: Trace, ax=None):
    """dq voltage commands, V."""
    lines = [(trace.u_dq_ref[:, 0], "-", "$u_d^*$"), (trace.u_dq_ref[:, 1], "-", "$u_q^*$")]
    return _panel(ax, trace, "dq voltage commands", "u / V", lines)


def overview_figure(trace: Trace, title: str = ""):
    """All five panels in one figure."""
    fig, axes = plt.subplots(5, 1, figsize=(8, 13), sharex=True)
    for plot, ax in zip(
        (plot_speed, plot_dq_currents, plot_phase_currents, plot_torque, plot_voltages), axes, strict=True
    ):
        plot(trace, ax)
    for ax in axes[:-1]:
        ax.set_xlabel("")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig


def save_demo_figures(trace: Trace, out_dir: Path, title: str = "") -> list[Path]:
    """Write ``overview.png`` and one PNG per panel into ``out_dir``; returns the paths."""
    out_dir = Path(out_dir)
    paths = [save_figure(overview_figure(trace, title), out_dir / "overview.png")]
    for name, plot in (
        ("speed", plot_speed),
        ("currents_dq", plot_dq_currents),
        ("currents_abc", plot_phase_currents),
        ("torque", plot_torque),
        ("voltages_dq", plot_voltages),
    ):
        fig, ax = plt.subplots(figsize=(7, 3))
        plot(trace, ax)
        fig.tight_layout()
        paths.append(save_figure(fig, out_dir / f"{name}.png"))
    return paths
