"""Figure of an identification: measured against fitted currents and speed, and the current residuals."""

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
    """Five panels: i_d and i_q over the whole log, i_q over the ``zoom_s`` s at the middle, the current
    residuals (fitted minus measured) against the noise level the fit estimated, and the speed (r/min).

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
    measured = log.i_dq[1 : n_w * W + 1]
    rpm = 30.0 / np.pi
    fig, axes = plt.subplots(5, 1, figsize=(10, 12.5))
    mid = 0.5 * (t[0] + t[-1])
    zoom = (t >= mid) & (t < mid + zoom_s)
    panels = (
        (axes[0], np.ones_like(t, bool), 0, "$i_d$ / A", "d-axis current"),
        (axes[1], np.ones_like(t, bool), 1, "$i_q$ / A", "q-axis current"),
        (axes[2], zoom, 1, "$i_q$ / A", f"q-axis current, {1e3 * zoom_s:.0f} ms at the middle of the log"),
    )
    for ax, sel, k, ylabel, title in panels:
        ax.plot(t[sel], measured[sel, k], ".", ms=1.5, color="0.55", label="measured")
        ax.plot(t[sel], i_fit[sel, k], "-", lw=0.9, color="C0", label="fitted model")
        ax.set(ylabel=ylabel, title=title)
    residual = i_fit - measured
    sigma = result.summary["noise_estimate"]
    for k, (name, key) in enumerate((("$i_d$", "i_d_A"), ("$i_q$", "i_q_A"))):
        axes[3].plot(t, residual[:, k], lw=0.5, color=f"C{k + 1}", alpha=0.8, label=f"{name} residual")
        axes[3].axhline(2.0 * sigma[key], color=f"C{k + 1}", ls=":", lw=1.0, label=f"{name}: +-2 x noise")
        axes[3].axhline(-2.0 * sigma[key], color=f"C{k + 1}", ls=":", lw=1.0)
    axes[3].set(
        ylabel="fitted - measured / A", title="Current residuals (white and inside +-2 x noise: a good fit)"
    )
    axes[4].plot(t, rpm * log.omega_m[1 : n_w * W + 1], "-", color="0.6", lw=2.2, label="measured")
    axes[4].plot(t, rpm * w_fit, "-", lw=0.9, color="C0", label="fitted model")
    axes[4].set(ylabel="n / (r/min)", title="speed")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.set_xlabel("t / s")
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize=8)
    fig.tight_layout()
    return fig


def save_fit_figure(result, path: Path) -> Path:
    """Write :func:`fit_figure` as PNG atomically."""
    return save_figure(fit_figure(result), Path(path))
