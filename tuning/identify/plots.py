"""Figure of an identification: measured against fitted currents and speed, and the current residuals."""

from pathlib import Path

import jax
import jax.numpy as jnp
import matplotlib.pyplot as plt
import numpy as np

from pmsmjax.plotting.traces import save_figure
from tuning.identify import electrical as el
from tuning.identify import mechanical as me
from tuning.identify.windows import segment_windows

__all__ = ["fit_figure", "save_fit_figure"]

#: Block length of the residual panel's RMS, s.
RESIDUAL_BLOCK_S = 0.01


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
        # samples 1..W of every window (windows laid per capture in a burst log)
        starts = W * np.arange(n_w) if log.captures == 1 else segment_windows(log.segments, W)[0]
        rows = (starts[:, None] + np.arange(1, W + 1)[None, :]).reshape(-1)
        t = log.time[rows]
        i_fit = sim.reshape(-1, 2)
        md = me.MechanicalData.from_log(log, W, 1.0, fit.mechanical.pole_pairs)
        w_fit = np.asarray(me.simulate_speed(fit.pmap, theta, md)).reshape(-1)
    measured = log.i_dq[rows]
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
    # The residuals themselves are a band of noise at any zoom that shows the whole log; their RMS over
    # short blocks, over the noise level, is flat at 1 where the model explains everything but noise and
    # rises where it misses something.
    residual = i_fit - measured
    sigma = result.summary["noise_estimate"]
    block = max(1, int(round(RESIDUAL_BLOCK_S / float(np.median(np.diff(log.time))))))
    n_b = t.size // block
    t_b = t[: n_b * block].reshape(n_b, block)[:, 0]
    for k, (name, key) in enumerate((("$i_d$", "i_d_A"), ("$i_q$", "i_q_A"))):
        rms = np.sqrt(np.mean(residual[: n_b * block, k].reshape(n_b, block) ** 2, axis=1))
        axes[3].step(t_b, rms / sigma[key], where="post", lw=1.0, color=f"C{k + 1}", label=name)
    axes[3].axhline(1.0, color="k", ls=":", lw=1.0, label="noise only")
    axes[3].set_ylim(0.0, None)
    axes[3].set(
        ylabel="residual RMS / noise",
        title=f"Current residuals (fitted - measured): RMS over {1e3 * RESIDUAL_BLOCK_S:g} ms blocks / noise "
        "level (1: only noise left)",
    )
    axes[4].plot(t, rpm * log.omega_m[rows], "-", color="0.6", lw=2.2, label="measured")
    axes[4].plot(t, rpm * w_fit, "-", lw=0.9, color="C0", label="fitted model")
    axes[4].set(ylabel="n / (r/min)", title="speed")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.set_xlabel("t / s")
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize=8)
    fig.tight_layout()
    return fig


def save_fit_figure(result, path: Path) -> Path:
    """Write [`fit_figure`][tuning.identify.plots.fit_figure] as PNG atomically."""
    return save_figure(fit_figure(result), Path(path))
