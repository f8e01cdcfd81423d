"""Figures in the style of the book's result plots (speed, currents, torque, voltages against time)."""

from pathlib import Path
from types import SimpleNamespace
from typing import TYPE_CHECKING

import numpy as np

from pmsmjax.io.logs import atomic_write
from pmsmjax.units import rad_s_to_rpm


def _pyplot():
    """``matplotlib.pyplot``, loaded when a figure is first drawn: a command whose figures are drawn by a
    figure worker never loads it. No backend is forced: matplotlib falls back to Agg without a display
    (the CLI), and notebooks keep their inline backend."""
    import matplotlib.pyplot as plt

    return plt


if TYPE_CHECKING:  # the figures read arrays only: drawing them loads no JAX (a figure worker does not)
    from pmsmjax.trace import Trace


def save_figure(fig, path: Path) -> Path:
    """Write a figure as PNG atomically ([`pmsmjax.io.logs.atomic_write`][pmsmjax.io.logs.atomic_write]) and
    close it."""
    try:
        return atomic_write(path, lambda f: fig.savefig(f, format="png", dpi=120, bbox_inches="tight"))
    finally:
        _pyplot().close(fig)


#: Legends sit outside the plot area, to the right, so they never hide a curve.
LEGEND = dict(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize=9)
LIMIT_STYLE = dict(color="tab:red", ls=":", lw=1.2)


def _panel(ax, trace: "Trace", title: str, ylabel: str, lines, limits=()):
    """Draw ``lines`` = [(values (N,), matplotlib format, label), ...] against time on ``ax``, and
    ``limits`` = [(value, label), ...] as red dotted horizontal lines at +value, and at -value when the
    curves go that way (a line far below positive-only curves would only squeeze them)."""
    ax = ax or _pyplot().subplots(figsize=(8, 3))[1]
    t = np.asarray(trace.t)
    low = 0.0
    for values, fmt, label in lines:
        values = np.asarray(values)
        low = min(low, float(np.min(values)))
        ax.plot(t, values, fmt, lw=1.2 if fmt == "-" else 0.9, label=label)
    for value, label in limits:
        if value is not None and np.isfinite(value):
            ax.axhline(value, **LIMIT_STYLE, label=label)
            if low < -0.2 * value:
                ax.axhline(-value, **LIMIT_STYLE)
    ax.set(xlabel="t / s", ylabel=ylabel, title=title)
    ax.grid(alpha=0.3)
    ax.legend(**LEGEND)
    return ax


def plot_speed(trace: "Trace", ax=None):
    """Speed and its reference, r/min."""
    lines = [(rad_s_to_rpm(trace.speed_ref), "k--", "reference"), (trace.speed_rpm, "-", "speed")]
    return _panel(ax, trace, "Speed", "n / (r/min)", lines)


def plot_dq_currents(trace: "Trace", ax=None, current_limit_a: float | None = None):
    """dq currents and their references, A; ``current_limit_a``: the controller's limit on |i_dq*|."""
    lines = [(trace.i_dq[:, 0], "-", "$i_d$"), (trace.i_dq[:, 1], "-", "$i_q$")]
    lines.append((trace.i_dq_ref[:, 0], "k:", "$i_d^*$"))
    lines.append((trace.i_dq_ref[:, 1], "k--", "$i_q^*$"))
    return _panel(ax, trace, "dq currents", "i / A", lines, [(current_limit_a, "current limit")])


def plot_phase_currents(trace: "Trace", ax=None, current_limit_a: float | None = None):
    """Phase currents, A, with the peak current limit."""
    lines = [(trace.i_abc[:, k], "-", f"$i_{name}$") for k, name in enumerate("abc")]
    return _panel(ax, trace, "Phase currents", "i / A", lines, [(current_limit_a, "current limit")])


def plot_torque(trace: "Trace", ax=None):
    """Electromagnetic and load torque, N m."""
    lines = [(trace.torque, "-", "$T_e$"), (trace.load_torque, "k--", "$T_L$")]
    return _panel(ax, trace, "Torque", "T / (N m)", lines)


def plot_voltages(trace: "Trace", ax=None, voltage_limit_v: float | None = None):
    """dq voltage commands and their magnitude, V, with the modulator's linear limit."""
    u = np.asarray(trace.u_dq_ref)
    lines = [
        (u[:, 0], "-", "$u_d^*$"),
        (u[:, 1], "-", "$u_q^*$"),
        (np.hypot(u[:, 0], u[:, 1]), "k-", "$|u^*|$"),
    ]
    return _panel(ax, trace, "dq voltage commands", "u / V", lines, [(voltage_limit_v, "voltage limit")])


def _panels(current_limit_a, voltage_limit_v):
    return (
        ("speed", plot_speed),
        ("currents_dq", lambda tr, ax: plot_dq_currents(tr, ax, current_limit_a)),
        ("currents_abc", lambda tr, ax: plot_phase_currents(tr, ax, current_limit_a)),
        ("torque", plot_torque),
        ("voltages_dq", lambda tr, ax: plot_voltages(tr, ax, voltage_limit_v)),
    )


def overview_figure(
    trace: "Trace",
    title: str = "",
    current_limit_a: float | None = None,
    voltage_limit_v: float | None = None,
):
    """All five panels in one figure (limits drawn when given: A, V)."""
    panels = _panels(current_limit_a, voltage_limit_v)
    fig, axes = _pyplot().subplots(len(panels), 1, figsize=(9, 13), sharex=True)
    for (_, plot), ax in zip(panels, axes, strict=True):
        plot(trace, ax)
    for ax in axes[:-1]:
        ax.set_xlabel("")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig


#: The trace signals the figures draw.
FIGURE_SIGNALS = (
    "t",
    "speed_ref",
    "speed_rpm",
    "i_dq",
    "i_dq_ref",
    "i_abc",
    "torque",
    "load_torque",
    "u_dq_ref",
)


def figure_data(trace: "Trace") -> SimpleNamespace:
    """What the figures read of ``trace`` (its [`FIGURE_SIGNALS`][pmsmjax.plotting.traces.FIGURE_SIGNALS] as
    NumPy arrays): picklable, and unpickled without JAX, for a figure worker."""
    return SimpleNamespace(**{name: np.asarray(getattr(trace, name)) for name in FIGURE_SIGNALS})


def save_overview_figure(
    trace: "Trace", path: Path, title: str = "", current_limit_a: float | None = None,
    voltage_limit_v: float | None = None,
) -> Path:  # fmt: skip
    """Write [`overview_figure`][pmsmjax.plotting.traces.overview_figure] to ``path``; returns it."""
    return save_figure(overview_figure(trace, title, current_limit_a, voltage_limit_v), path)


def save_panel_figures(
    trace: "Trace", out_dir: Path, current_limit_a: float | None = None, voltage_limit_v: float | None = None
) -> list[Path]:
    """Write one PNG per panel (speed, dq and phase currents, torque, voltages) into ``out_dir``; returns
    the paths."""
    paths = []
    for name, plot in _panels(current_limit_a, voltage_limit_v):
        fig, ax = _pyplot().subplots(figsize=(8, 3))
        plot(trace, ax)
        fig.tight_layout()
        paths.append(save_figure(fig, Path(out_dir) / f"{name}.png"))
    return paths


def save_demo_figures(
    trace: "Trace",
    out_dir: Path,
    title: str = "",
    current_limit_a: float | None = None,
    voltage_limit_v: float | None = None,
    workers=(),
) -> list[Path]:
    """Write ``overview.png`` and one PNG per panel into ``out_dir``; returns the paths.

    With ``workers`` (the command line's ``FigureWorker``: ``submit`` a call,
    collect its ``result``) the overview and the panels are drawn there, at the same time (the same files);
    what has no worker is drawn here."""
    out_dir = Path(out_dir)
    data = figure_data(trace) if workers else trace
    jobs = [
        (save_overview_figure, (data, out_dir / "overview.png", title, current_limit_a, voltage_limit_v)),
        (save_panel_figures, (data, out_dir, current_limit_a, voltage_limit_v)),
    ]
    workers = list(workers)[: len(jobs)]
    for worker, (function, args) in zip(workers, jobs, strict=False):
        worker.submit(function, *args)
    here = [function(*args) for function, args in jobs[len(workers) :]]
    done = [worker.result() for worker in workers] + here
    return [done[0], *done[1]]
