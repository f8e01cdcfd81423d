"""Figures of the six-phase drive: the 64 voltage vectors, the PWM comparison's voltage and current
trajectories in alpha-beta and z1-z2, its harmonic table, and a six-phase run's z1-z2 currents."""

import matplotlib.pyplot as plt
import numpy as np

from pmsmjax.frames.multiphase import SIX_PHASE, vsd
from pmsmjax.inverters.multiphase_vectors import space_vectors


def vectors_figure(u_dc: float = 1.0):
    """The 64 switching states' voltages on alpha-beta and z1-z2 (per unit of ``u_dc`` if it is 1)."""
    sv = space_vectors(SIX_PHASE)
    v = u_dc * sv.vectors
    mag = np.round(np.hypot(v[:, 0], v[:, 1]) / u_dc, 4)
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.8))
    groups = [("L", sv.large, "C3"), ("ML", sv.second, "C1")]
    rest = np.setdiff1d(np.arange(64), np.concatenate([sv.large, sv.second]))
    for ax, (i, j), title in zip(axes, ((0, 1), (2, 3)), ("alpha-beta", "z1-z2"), strict=True):
        ax.plot(v[rest, i], v[rest, j], "o", color="0.6", ms=4, label="medium, small, zero")
        for name, idx, color in groups:
            ax.plot(v[idx, i], v[idx, j], "o", color=color, ms=6, label=name)
            for k in idx:
                ax.annotate(str(k), (v[k, i], v[k, j]), fontsize=6, xytext=(2, 2), textcoords="offset points")
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
        ax.set_title(f"64 switching states on {title}")
        unit = "V" if u_dc != 1.0 else "per unit of $U_{dc}$"
        ax.set_xlabel(f"{title.split('-')[0]} / {unit}")
        ax.set_ylabel(f"{title.split('-')[1]} / {unit}")
    axes[0].legend(fontsize=7, loc="lower left")
    fig.suptitle(
        f"four alpha-beta lengths: {', '.join(str(x) for x in np.unique(mag)[1:])} (x U_dc)", fontsize=9
    )
    fig.tight_layout()
    return fig


def trajectories_figure(result: dict, names):
    """Per variant: each period's average voltage on alpha-beta and z1-z2, and the currents in both planes."""
    waves = result["waves"]
    five = result["settings"].get("phases", 6) == 5
    plane, a, b = ("x-y", "x", "y") if five else ("z1-z2", "z1", "z2")
    fig, axes = plt.subplots(2, 2, figsize=(10, 9))
    for k, name in enumerate(names):
        w = waves[name]
        u, i = w["u_vsd_period"], w["i_vsd"]
        axes[0, 0].plot(u[:, 0], u[:, 1], ".", ms=2, color=f"C{k}", label=name)
        axes[0, 1].plot(u[:, 2], u[:, 3], ".", ms=2, color=f"C{k}", label=name)
        axes[1, 0].plot(i[:, 0], i[:, 1], lw=0.5, color=f"C{k}", label=name)
        axes[1, 1].plot(i[:, 2], i[:, 3], lw=0.5, color=f"C{k}", label=name)
    titles = (
        ("period-average voltage, alpha-beta", "$u_\\alpha$ / V", "$u_\\beta$ / V"),
        (f"period-average voltage, {plane}", f"$u_{{{a}}}$ / V", f"$u_{{{b}}}$ / V"),
        ("current, alpha-beta", "$i_\\alpha$ / A", "$i_\\beta$ / A"),
        (f"current, {plane}", f"$i_{{{a}}}$ / A", f"$i_{{{b}}}$ / A"),
    )
    for ax, (title, xl, yl) in zip(axes.ravel(), titles, strict=True):
        ax.set(title=title, xlabel=xl, ylabel=yl)
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=7, markerscale=4)
    fig.tight_layout()
    return fig


def harmonics_figure(result: dict):
    """5th and 7th (five phases: 3rd and 7th) harmonic phase currents and current THD of every variant."""
    entries = result["entries"]
    names = list(entries)
    five = result["settings"].get("phases", 6) == 5
    h1, h2 = (3, 7) if five else (5, 7)
    nth = {3: "3rd", 5: "5th", 7: "7th"}
    x = np.arange(len(names))
    fig, (ax_h, ax_t) = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    ax_h.bar(x - 0.2, [entries[n][f"harmonic_{h1}_current_a"] for n in names], 0.4, label=nth[h1])
    ax_h.bar(x + 0.2, [entries[n][f"harmonic_{h2}_current_a"] for n in names], 0.4, label=nth[h2])
    ax_h.set(
        ylabel="amplitude / A",
        title=f"{nth[h1]} and {nth[h2]} harmonic phase currents "
        f"(mean of the {'five' if five else 'six'} phases)",
    )
    ax_h.legend(fontsize=8)
    ax_t.bar(x, [entries[n]["current_thd_pct"] for n in names], 0.6, color="C2")
    f_max = result["settings"]["thd_max_frequency_hz"]
    ax_t.set(ylabel="THD / %", title=f"phase-current THD (components up to {f_max / 1e3:g} kHz)")
    ax_t.set_yscale("log")
    ax_t.set_xticks(x, names, rotation=30, ha="right", fontsize=7)
    for ax in (ax_h, ax_t):
        ax.grid(alpha=0.3, axis="y")
    fig.tight_layout()
    return fig


def z_currents_figure(trace, title: str = "", layout=None):
    """A six-phase run: the phase currents of both sets and the z1-z2 currents against time; with
    ``layout=FIVE_PHASE`` a five-phase run's phase currents and x-y currents."""
    layout = SIX_PHASE if layout is None else layout
    six = layout == SIX_PHASE
    t = np.asarray(trace.t)
    i = np.asarray(trace.i_abc)
    iz = np.asarray(vsd(i, layout))[:, 2:4]
    fig, (ax_p, ax_z) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for k, name in enumerate("ABCUVW" if six else "ABCDE"[: layout.n]):
        ax_p.plot(t, i[:, k], lw=0.8, ls="-" if k < 3 or not six else "--", label=f"$i_{name}$")
    ax_p.set(ylabel="i / A", title="phase currents (sets ABC solid, UVW dashed)" if six else "phase currents")
    ax_p.legend(fontsize=7, ncol=6, loc="upper right")
    a, b = ("z1", "z2") if six else ("x", "y")
    ax_z.plot(t, iz[:, 0], lw=0.8, label=f"$i_{{{a}}}$")
    ax_z.plot(t, iz[:, 1], lw=0.8, label=f"$i_{{{b}}}$")
    ax_z.set(xlabel="t / s", ylabel="i / A", title=f"{a}-{b} currents")
    ax_z.legend(fontsize=8)
    for ax in (ax_p, ax_z):
        ax.grid(alpha=0.3)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig
