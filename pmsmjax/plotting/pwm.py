"""Figures of the PWM comparison ([`pmsmjax.jobs.pwm_comparison`][pmsmjax.jobs.pwm_comparison]): waveforms,
spectra and the THD table of the three-phase comparison;
[`comparison_figures`][pmsmjax.plotting.pwm.comparison_figures] picks those of any phase count (the six- and
five-phase ones are in [`six_phase`][pmsmjax.plotting.six_phase]).

The variants differ only in the switching ripple, which is a few per cent of the current: drawn on top of
each other they are indistinguishable. So every figure gives each variant its own panel or its own
signal (the ripple, the current minus its fundamental) and labels the numbers it compares.
"""

import matplotlib.pyplot as plt
import numpy as np

LEGEND = dict(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize=8)
STYLES = ("-", "--", "-.", ":")


def _fundamental(t: np.ndarray, x: np.ndarray, cycles: int) -> np.ndarray:
    """The least-squares fundamental (plus mean) of ``x (N,)`` sampled at ``t``, ``cycles`` periods long."""
    w = 2.0 * np.pi * cycles / (t[-1] - t[0] + (t[1] - t[0]))
    A = np.stack([np.cos(w * t), np.sin(w * t), np.ones_like(t)], axis=1)
    return A @ np.linalg.lstsq(A, x, rcond=None)[0]


def waveform_figure(result: dict, names, zoom_periods: int = 4):
    """Phase-a current over the window; then, over the first ``zoom_periods`` PWM periods, each variant's
    phase voltage (its own panel) and the current ripple (i_a minus its fundamental) of all of them."""
    waves = result["waves"]
    Ts = result["settings"]["Ts_s"]
    cycles = result["settings"]["window_cycles"]
    n = len(names)
    fig = plt.figure(figsize=(9, 3.4 + 1.7 * n + 2.6))
    grid = fig.add_gridspec(2 + n, 1, height_ratios=[2.2] + [1.1] * n + [1.8], hspace=0.75)
    ax_i = fig.add_subplot(grid[0])
    for k, name in enumerate(names):
        w = waves[name]
        ax_i.plot(1e3 * w["t_i"], w["i_abc"][:, 0], STYLES[k % 4], lw=1.0, color=f"C{k}", label=name)
    ax_i.set(
        xlabel="t / ms (analysis window)",
        ylabel="$i_a$ / A",
        title="Phase current (the variants differ only in the ripple, below)",
    )
    ax_i.legend(**LEGEND)
    ax_i.grid(alpha=0.3)
    # Zoom where phase a peaks: there the modulators' zero-sequence voltages differ most (at the zero
    # crossing of phase a they nearly coincide).
    w0 = waves[names[0]]
    peak = float(w0["t_i"][np.argmax(np.abs(_fundamental(w0["t_i"], w0["i_abc"][:, 0], cycles)))])
    t_start = max(0.0, np.floor(peak / Ts - zoom_periods / 2)) * Ts
    t_end = t_start + zoom_periods * Ts
    ax_r = fig.add_subplot(grid[1 + n])
    first = None
    for k, name in enumerate(names):
        w = waves[name]
        ax_u = fig.add_subplot(grid[1 + k], sharex=first)
        first = first or ax_u
        edges = w["t_u"]
        keep_u = (edges[:-1] >= t_start - 1e-12) & (edges[:-1] < t_end - 1e-12)
        t_u = np.append(edges[:-1][keep_u], t_end)
        ax_u.stairs(w["u_abc"][keep_u, 0], 1e6 * t_u, color=f"C{k}", lw=1.3, baseline=None, label=name)
        ax_u.set(
            ylabel="$u_{aN}$ / V", title=f"{name}: phase voltage over {zoom_periods} PWM periods at the peak"
        )
        ax_u.grid(alpha=0.3)
        ax_u.tick_params(labelbottom=False)
        keep_i = (w["t_i"] >= t_start) & (w["t_i"] <= t_end)
        ripple = w["i_abc"][:, 0] - _fundamental(w["t_i"], w["i_abc"][:, 0], cycles)
        ax_r.plot(1e6 * w["t_i"][keep_i], ripple[keep_i], STYLES[k % 4], lw=1.2, color=f"C{k}", label=name)
    ax_r.sharex(first)
    ax_r.set(
        xlabel="t / us (analysis window)",
        ylabel="ripple / A",
        title=f"Current ripple ($i_a$ minus its fundamental) over the same {zoom_periods} PWM periods",
    )
    ax_r.legend(**LEGEND)
    ax_r.grid(alpha=0.3)
    return fig


def spectrum_figure(result: dict, names):
    """Phase-voltage (top) and phase-current (bottom) amplitude spectra of phase a, one column per variant,
    log scale, up to the THD limit."""
    n = len(names)
    fig, axes = plt.subplots(2, n, figsize=(4.6 * n + 1.0, 6.5), sharex=True, sharey="row", squeeze=False)
    f_max = result["settings"]["thd_max_frequency_hz"]
    for k, name in enumerate(names):
        spectra = result["spectra"][name]
        entry = result["entries"][name]
        for row, (key, unit, floor, thd_key) in enumerate(
            (("phase_voltage", "V", 1e-2, "voltage_thd_pct"), ("current", "A", 1e-5, "current_thd_pct"))
        ):
            ax = axes[row, k]
            s = spectra[key]
            f, a = s.frequencies_hz[1:], s.amplitudes[1:, 0]
            shown = a > floor
            ax.vlines(1e-3 * f[shown], floor, a[shown], color=f"C{k}", lw=0.8)
            ax.set_yscale("log")
            ax.set_ylim(floor, None)
            what = "phase voltage" if row == 0 else "phase current"
            ax.set_title(f"{name}: {what}, THD {entry[thd_key]:.2f} %", fontsize=10)
            if k == 0:
                ax.set_ylabel(f"amplitude / {unit}")
            ax.grid(alpha=0.3)
        axes[1, k].set_xlabel("f / kHz")
    fig.suptitle(
        f"Spectra of phase a (voltage exact from the switching instants; THD up to {f_max / 1e3:g} kHz)",
        fontsize=11,
    )
    fig.tight_layout()
    return fig


def thd_figure(result: dict):
    """Current THD of every modulator: averaged, switching, switching with dead time; each bar labelled."""
    entries = result["entries"]
    modulators = list(dict.fromkeys(e["modulator"] for e in entries.values()))
    variants = [
        ("", "averaged bridge (no PWM ripple in the model)"),
        ("_switching", "switching bridge"),
        ("_switching_deadtime", "switching bridge + dead time"),
    ]
    fig, ax = plt.subplots(figsize=(9, 4.2))
    width = 0.8 / len(variants)
    x = np.arange(len(modulators))
    top = 0.0
    for k, (suffix, label) in enumerate(variants):
        values = np.array([entries.get(m + suffix, {}).get("current_thd_pct", np.nan) for m in modulators])
        bars = ax.bar(x + (k - 1) * width, values, width, label=label, color=f"C{k}")
        ax.bar_label(
            bars, labels=[f"{v:.2f}" if np.isfinite(v) else "" for v in values], fontsize=8, padding=2
        )
        top = max(top, np.nanmax(values) if np.isfinite(values).any() else 0.0)
    ax.set_xticks(x, modulators)
    ax.set_ylim(0.0, 1.18 * top if top > 0 else 1.0)
    f_max = result["settings"]["thd_max_frequency_hz"]
    ax.set(ylabel="current THD / %", title=f"Phase-current THD (components up to {f_max / 1e3:g} kHz)")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=3, fontsize=8, frameon=False)
    ax.grid(alpha=0.3, axis="y")
    fig.tight_layout()
    return fig


def comparison_figures(result: dict) -> list:
    """``[(file name, figure)]`` of a
    [`pmsmjax.jobs.pwm_comparison.compare`][pmsmjax.jobs.pwm_comparison.compare] result.

    Three phases: ``pwm_waveforms.png`` and ``pwm_spectra.png`` (sinusoidal PWM and SVPWM on the switching
    bridge, those compared) and ``pwm_thd.png``. ``n`` = 6 or 5 phases: ``pwm<n>_trajectories.png`` (every
    switching variant on both VSD planes) and ``pwm<n>_harmonics.png``, for six phases also
    ``pwm6_vectors.png`` (the 64 switching states) first.
    """
    from pmsmjax.plotting.six_phase import harmonics_figure, trajectories_figure, vectors_figure

    settings = result["settings"]
    modulators, phases = settings["modulators"], settings.get("phases", 3)
    if phases == 3:
        shown = [m + "_switching" for m in ("sinusoidal", "svpwm") if m in modulators]
        return [
            ("pwm_waveforms.png", waveform_figure(result, shown)),
            ("pwm_spectra.png", spectrum_figure(result, shown)),
            ("pwm_thd.png", thd_figure(result)),
        ]
    shown = [m + "_switching" for m in modulators if m + "_switching" in result["waves"]]
    figures = [
        (f"pwm{phases}_trajectories.png", trajectories_figure(result, shown)),
        (f"pwm{phases}_harmonics.png", harmonics_figure(result)),
    ]
    if phases == 6:  # the 64 vectors' figure is six-phase
        figures.insert(0, ("pwm6_vectors.png", vectors_figure(settings["u_dc_v"])))
    return figures
