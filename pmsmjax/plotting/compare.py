"""Figures of the controller comparison
([`pmsmjax.jobs.control_comparison`][pmsmjax.jobs.control_comparison])."""

import matplotlib.pyplot as plt
import numpy as np

from pmsmjax.units import rad_s_to_rpm


def speed_figure(
    result: dict, title: str = "Speed step from rest, then load step", load_time_s: float | None = None
):
    """Speed of every controller against time, with the reference; a zoom on the load step (at
    ``load_time_s``, s, default the settings') below."""
    traces = result["traces"]
    load_time = result["settings"]["load_time_s"] if load_time_s is None else load_time_s
    fig, (ax, ax_zoom) = plt.subplots(2, 1, figsize=(8, 6.5))
    first = next(iter(traces.values()))
    for axis in (ax, ax_zoom):
        axis.plot(
            np.asarray(first.t), rad_s_to_rpm(np.asarray(first.speed_ref)), "k--", lw=0.9, label="reference"
        )
        for name, tr in traces.items():
            axis.plot(np.asarray(tr.t), rad_s_to_rpm(np.asarray(tr.omega_m)), lw=1.1, label=name)
        axis.grid(alpha=0.3)
        axis.set(xlabel="t / s", ylabel="n / (r/min)")
    ax.set_title(title)
    ax.legend(loc="lower right", fontsize=8)
    ax_zoom.set_xlim(load_time - 0.01, min(load_time + 0.15, float(first.t[-1])))
    lows = [
        np.min(rad_s_to_rpm(np.asarray(tr.omega_m))[np.asarray(tr.t) >= load_time]) for tr in traces.values()
    ]
    top = float(rad_s_to_rpm(np.asarray(first.speed_ref))[-1])
    ax_zoom.set_ylim(min(lows) - 0.05 * (top - min(lows)) - 1.0, top + 0.15 * (top - min(lows)) + 1.0)
    ax_zoom.set_title(f"Load step at {load_time:g} s (zoom)")
    fig.tight_layout()
    return fig


def ripple_figure(result: dict):
    """Per controller, over the analysis window: phase-a current (left) and torque (right)."""
    windows = result["windows"]
    names = list(windows)
    fig, axes = plt.subplots(len(names), 2, figsize=(10, 2.4 * len(names) + 0.6), squeeze=False)
    for row, name in zip(axes, names, strict=True):
        w = windows[name]
        e = result["controllers"][name]
        t_ms = 1e3 * w["t"]
        row[0].plot(t_ms, w["i_abc"][:, 0], lw=0.6)
        row[0].set(ylabel="$i_a$ / A", title=f"{name}: phase current, THD {e['current_thd_pct']:.2f} %")
        row[1].plot(t_ms, w["torque"], lw=0.6, color="C1")
        row[1].set(
            ylabel="$T_e$ / (N m)",
            title=f"{name}: torque, ripple {e['torque_ripple_nm']:.3f} N m RMS",
        )
        for ax in row:
            ax.grid(alpha=0.3)
            ax.set_xlabel("t / ms (analysis window)")
    fig.tight_layout()
    return fig


def flux_figure(result: dict):
    """Per controller, over the analysis window: the stator flux locus in the alpha-beta plane (left) and
    its magnitude against time (right)."""
    windows = result["windows"]
    names = list(windows)
    fig, axes = plt.subplots(len(names), 2, figsize=(10, 2.6 * len(names) + 0.6), squeeze=False)
    for row, name in zip(axes, names, strict=True):
        psi = windows[name]["psi_ab"]
        e = result["controllers"][name]
        row[0].plot(psi[:, 0], psi[:, 1], lw=0.5)
        row[0].set(xlabel=r"$\psi_\alpha$ / Wb", ylabel=r"$\psi_\beta$ / Wb", title=f"{name}: flux locus")
        row[0].set_aspect("equal", adjustable="datalim")
        row[1].plot(1e3 * windows[name]["t"], np.hypot(psi[:, 0], psi[:, 1]), lw=0.6, color="C2")
        row[1].set(
            xlabel="t / ms (analysis window)",
            ylabel=r"$|\psi_s|$ / Wb",
            title=f"{name}: flux magnitude, ripple {1e3 * e['flux_ripple_wb']:.2f} mWb RMS",
        )
        for ax in row:
            ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig
