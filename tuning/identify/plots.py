"""Figure of an identification: measured against fitted currents and speed."""

from pathlib import Path

import jax
import jax.numpy as jnp
import matplotlib.pyplot as plt
import numpy as np

from pmsmjax.plotting import save_figure

from . import electrical as el
from . import mechanical as me

__all__ = ["fit_figure", "save_fit_figure"]


def fit_figure(result, zoom_s: float = 0.05):
    """Four panels: i_d, i_q (whole log), i_q over the ``zoom_s`` s at the middle, and the speed.

    Fitted currents are the electrical model run from each window's measured start; the fitted speed is
    the mechanical model run over the same windows from the measured speed at each window start.
    """
    with jax.enable_x64(True):
        fit, log = result.fit, result.log
        d, theta = fit.electrical, jnp.asarray(fit.theta)
        sim = np.asarray(el.simulate_windows(fit.pmap, theta, d.i[:, 0, :], d))
        n_w, W = sim.shape[:2]
        t = log.time[1 : n_w * W + 1]
        i_fit = sim.reshape(-1, 2)
        md = me.MechanicalData.from_log(log, W, 1.0, fit.mechanical.pole_pairs)
        w_fit = np.asarray(me.simulate_speed(fit.pmap, theta, md)).reshape(-1)
    fig, axes = plt.subplots(4, 1, figsize=(9, 10))
    mid = 0.5 * (t[0] + t[-1])
    zoom = (t >= mid) & (t < mid + zoom_s)
    panels = (
        (axes[0], np.ones_like(t, bool), 0, "i_d / A", "d-axis current"),
        (axes[1], np.ones_like(t, bool), 1, "i_q / A", "q-axis current"),
        (axes[2], zoom, 1, "i_q / A", f"q-axis current, {1e3 * zoom_s:.0f} ms"),
    )
    for ax, sel, k, ylabel, title in panels:
        ax.plot(t[sel], log.i_dq[1 : n_w * W + 1, k][sel], ".", ms=1.5, color="0.6", label="measured")
        ax.plot(t[sel], i_fit[sel, k], "-", lw=0.9, label="fitted model")
        ax.set(ylabel=ylabel, title=title)
    axes[3].plot(t, log.omega_m[1 : n_w * W + 1], "-", color="0.6", lw=2, label="measured")
    axes[3].plot(t, w_fit, "-", lw=0.9, label="fitted model")
    axes[3].set(ylabel="omega_m / (rad/s)", title="speed", xlabel="t / s")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right")
    fig.tight_layout()
    return fig


def save_fit_figure(result, path: Path) -> Path:
    """Write :func:`fit_figure` as PNG atomically."""
    return save_figure(fit_figure(result), Path(path))
