"""Figures: a trace against time ([`traces`][pmsmjax.plotting.traces], re-exported here) and the figures of
the comparisons ([`compare`][pmsmjax.plotting.compare], [`observers`][pmsmjax.plotting.observers],
[`pwm`][pmsmjax.plotting.pwm], [`six_phase`][pmsmjax.plotting.six_phase]).
"""

from pmsmjax.plotting.traces import (
    LEGEND,
    LIMIT_STYLE,
    overview_figure,
    plot_dq_currents,
    plot_phase_currents,
    plot_speed,
    plot_torque,
    plot_voltages,
    save_demo_figures,
    save_figure,
)

__all__ = [
    "save_figure",
    "LEGEND",
    "LIMIT_STYLE",
    "plot_speed",
    "plot_dq_currents",
    "plot_phase_currents",
    "plot_torque",
    "plot_voltages",
    "overview_figure",
    "save_demo_figures",
]
