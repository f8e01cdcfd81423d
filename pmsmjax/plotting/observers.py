"""Figures of observers' estimates in the style of the book's chapter 5 plots: estimated against actual
angle and speed, and the angle error."""

import matplotlib.pyplot as plt
import numpy as np

from pmsmjax.analysis.observer_errors import angle_error, angle_error_modulo_pi
from pmsmjax.frames.three_phase import wrap_angle
from pmsmjax.units import rad_s_to_rpm

__all__ = ["observer_log_figure", "angle_error_figure"]


def observer_log_figure(
    time, theta_e, omega_m, truth: dict | None = None, title: str = "", modulo_pi: bool = False
):
    """Estimated angle (electrical rad) and speed (r/min) against time, with the truth where given
    (``truth``: ``theta_e`` electrical rad, ``omega_m`` mechanical rad/s), and the angle error in electrical
    degrees when the angle is known. ``modulo_pi``: the estimate is the d axis without its polarity (HF
    injection); the true angle is drawn and the error taken modulo pi. Returns the figure."""
    truth = truth or {}
    t = np.asarray(time)
    n_rows = 3 if "theta_e" in truth else 2
    fig, axes = plt.subplots(n_rows, 1, figsize=(8, 2.4 * n_rows), sharex=True)
    ax = axes[0]
    if "theta_e" in truth:
        actual = np.asarray(truth["theta_e"])
        if modulo_pi:
            actual = 0.5 * np.asarray(wrap_angle(2.0 * actual))
        ax.plot(t, actual, "k-", lw=1.0, label="actual (modulo pi)" if modulo_pi else "actual")
    ax.plot(t, np.asarray(theta_e), "-", lw=0.8, label="estimated")
    ax.set(ylabel="$\\theta_e$ / rad", title=title)
    ax = axes[1]
    if "omega_m" in truth:
        ax.plot(t, rad_s_to_rpm(np.asarray(truth["omega_m"])), "k-", lw=1.0, label="actual")
    ax.plot(t, rad_s_to_rpm(np.asarray(omega_m)), "-", lw=0.8, label="estimated")
    ax.set(ylabel="n / (r/min)")
    if "theta_e" in truth:
        error = angle_error_modulo_pi if modulo_pi else angle_error
        err = np.degrees(error(np.asarray(theta_e), np.asarray(truth["theta_e"])))
        axes[2].plot(t, err, "-", lw=0.8)
        axes[2].set(ylabel="angle error (modulo pi) / el. deg" if modulo_pi else "angle error / el. deg")
    for ax in axes:
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right")
    axes[-1].set(xlabel="t / s")
    fig.tight_layout()
    return fig


def angle_error_figure(time, errors_deg: dict, speed_rpm=None, title: str = "", ylim: float = 5.0):
    """Angle errors (electrical degrees) of several observers against time (``errors_deg``: name ->
    ``(N,)``), above the actual speed (r/min) when given. Returns the figure."""
    t = np.asarray(time)
    n_rows = 2 if speed_rpm is not None else 1
    fig, axes = plt.subplots(n_rows, 1, figsize=(8, 2.8 * n_rows), sharex=True, squeeze=False)
    ax = axes[0, 0]
    for name, e in errors_deg.items():
        ax.plot(t, np.asarray(e), "-", lw=0.7, label=name)
    ax.set(ylabel="angle error / el. deg", title=title, ylim=(-ylim, ylim))
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right", ncol=3, fontsize=8)
    if speed_rpm is not None:
        axes[1, 0].plot(t, np.asarray(speed_rpm), "k-", lw=1.0)
        axes[1, 0].set(ylabel="n / (r/min)")
        axes[1, 0].grid(alpha=0.3)
    axes[-1, 0].set(xlabel="t / s")
    fig.tight_layout()
    return fig
