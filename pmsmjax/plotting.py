"""Figures in the style of the book's result plots (speed, currents, torque, voltages against time)."""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only; never needs a display
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .trace import Trace  # noqa: E402
from .units import rad_s_to_rpm  # noqa: E402


def _save(fig, path: Path) -> Path:
    """Write a figure atomically (temporary file in the same folder, then rename)."""
    path = Path(path)
    tmp = path.with_name(f".{path.stem}.tmp{path.suffix}")
    fig.savefig(tmp, dpi=120, bbox_inches="tight")
    plt.close(fig)
    tmp.replace(path)
    return path


def plot_speed(trace: Trace, ax=None):
    """Speed and its reference, r/min."""
    ax = ax or plt.subplots(figsize=(7, 3))[1]
    t = np.asarray(trace.t)
    ax.plot(t, rad_s_to_rpm(np.asarray(trace.speed_ref)), "k--", lw=1, label="reference")
    ax.plot(t, rad_s_to_rpm(np.asarray(trace.omega_m)), lw=1.5, label="speed")
    ax.set(xlabel="t / s", ylabel="n / (r/min)", title="Speed")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right")
    return ax


def plot_dq_currents(trace: Trace, ax=None):
    """dq currents and references, A."""
    ax = ax or plt.subplots(figsize=(7, 3))[1]
    t = np.asarray(trace.t)
    i_dq, ref = np.asarray(trace.i_dq), np.asarray(trace.i_dq_ref)
    ax.plot(t, i_dq[:, 0], lw=1, label="$i_d$")
    ax.plot(t, i_dq[:, 1], lw=1, label="$i_q$")
    ax.plot(t, ref[:, 1], "k--", lw=0.8, label="$i_q^*$")
    ax.set(xlabel="t / s", ylabel="i / A", title="dq currents")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right")
    return ax


def plot_phase_currents(trace: Trace, ax=None):
    """Phase currents, A."""
    ax = ax or plt.subplots(figsize=(7, 3))[1]
    t = np.asarray(trace.t)
    for k, name in enumerate("abc"):
        ax.plot(t, np.asarray(trace.i_abc)[:, k], lw=0.8, label=f"$i_{name}$")
    ax.set(xlabel="t / s", ylabel="i / A", title="Phase currents")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right")
    return ax


def plot_torque(trace: Trace, ax=None):
    """Electromagnetic and load torque, N m."""
    ax = ax or plt.subplots(figsize=(7, 3))[1]
    t = np.asarray(trace.t)
    ax.plot(t, np.asarray(trace.torque), lw=1, label="$T_e$")
    ax.plot(t, np.asarray(trace.load_torque), "k--", lw=0.8, label="$T_L$")
    ax.set(xlabel="t / s", ylabel="T / (N m)", title="Torque")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right")
    return ax


def plot_voltages(trace: Trace, ax=None):
    """dq voltage commands, V."""
    ax = ax or plt.subplots(figsize=(7, 3))[1]
    t = np.asarray(trace.t)
    u = np.asarray(trace.u_dq_ref)
    ax.plot(t, u[:, 0], lw=1, label="$u_d^*$")
    ax.plot(t, u[:, 1], lw=1, label="$u_q^*$")
    ax.set(xlabel="t / s", ylabel="u / V", title="dq voltage commands")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right")
    return ax


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
    paths = [_save(overview_figure(trace, title), out_dir / "overview.png")]
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
        paths.append(_save(fig, out_dir / f"{name}.png"))
    return paths
