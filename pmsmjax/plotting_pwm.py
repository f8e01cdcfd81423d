"""Figures of the PWM comparison (:mod:`pmsmjax.pwm_compare`): waveforms, spectra and the THD table."""

import matplotlib.pyplot as plt
import numpy as np


def waveform_figure(result: dict, names, zoom_periods: int = 4):
    """Phase-a current over the window and a zoom on a few PWM periods with the phase-a voltage."""
    waves = result["waves"]
    Ts = result["settings"]["Ts_s"]
    fig, (ax_i, ax_z) = plt.subplots(2, 1, figsize=(8, 6.5))
    for name in names:
        w = waves[name]
        ax_i.plot(1e3 * w["t_i"], w["i_abc"][:, 0], lw=0.8, label=name)
    ax_i.set(xlabel="t / ms (analysis window)", ylabel="$i_a$ / A", title="Phase current")
    ax_i.legend(fontsize=8, loc="upper right")
    ax_i.grid(alpha=0.3)
    t_end = zoom_periods * Ts
    ax_u = ax_z.twinx()
    for k, name in enumerate(names):
        w = waves[name]
        keep_i = w["t_i"] <= t_end
        ax_z.plot(1e6 * w["t_i"][keep_i], w["i_abc"][keep_i, 0], "-", lw=1.0, color=f"C{k}", label=name)
        keep_u = w["t_u"][:-1] < t_end
        ax_u.step(
            1e6 * w["t_u"][:-1][keep_u], w["u_abc"][keep_u, 0], where="post", lw=0.6, color=f"C{k}", alpha=0.4
        )
    ax_z.set(xlabel="t / us", ylabel="$i_a$ / A (lines)", title=f"First {zoom_periods} PWM periods")
    ax_u.set_ylabel("$u_{aN}$ / V (steps)")
    ax_z.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def spectrum_figure(result: dict, names):
    """Phase-voltage and phase-current amplitude spectra (phase a), log scale, up to the THD limit."""
    fig, axes = plt.subplots(2, 1, figsize=(8, 6.5), sharex=True)
    for k, name in enumerate(names):
        spectra = result["spectra"][name]
        for ax, key, unit in zip(axes, ("phase_voltage", "current"), ("V", "A"), strict=True):
            s = spectra[key]
            f, a = s.frequencies_hz[1:], s.amplitudes[1:, 0]
            ax.semilogy(1e-3 * f, np.maximum(a, 1e-6), ".", ms=2.5, color=f"C{k}", label=name)
            ax.set_ylabel(f"amplitude / {unit}")
    axes[0].set_title("Phase-voltage spectrum (exact, from the switching instants)")
    axes[1].set_title("Phase-current spectrum")
    axes[1].set_xlabel("f / kHz")
    axes[0].set_ylim(1e-2, None)
    axes[1].set_ylim(1e-5, None)
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def thd_figure(result: dict):
    """Current THD of every modulator: averaged, switching, switching with dead time."""
    entries = result["entries"]
    modulators = list(dict.fromkeys(e["modulator"] for e in entries.values()))
    variants = [
        ("", "averaged"),
        ("_switching", "switching"),
        ("_switching_deadtime", "switching + dead time"),
    ]
    fig, ax = plt.subplots(figsize=(8, 3.5))
    width = 0.8 / len(variants)
    x = np.arange(len(modulators))
    for k, (suffix, label) in enumerate(variants):
        values = [entries.get(m + suffix, {}).get("current_thd_pct", np.nan) for m in modulators]
        ax.bar(x + (k - 1) * width, values, width, label=label)
    ax.set_xticks(x, modulators)
    f_max = result["settings"]["thd_max_frequency_hz"]
    ax.set(ylabel="current THD / %", title=f"Phase-current THD (components up to {f_max / 1e3:g} kHz)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, axis="y")
    fig.tight_layout()
    return fig
