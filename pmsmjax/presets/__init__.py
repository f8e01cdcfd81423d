"""Ready-made drives: the book's constants ([`book_constants`][pmsmjax.presets.book_constants]), the book's
three-phase drive ([`three_phase`][pmsmjax.presets.three_phase], re-exported here), the six- and five-phase
drives ([`six_phase`][pmsmjax.presets.six_phase], [`five_phase`][pmsmjax.presets.five_phase]), the control
methods by name ([`control_methods`][pmsmjax.presets.control_methods]) and the motor files in ``motors/``.

The re-exported names are imported on first use (PEP 562), so that ``pmsmjax.presets.book_constants``
reads without loading JAX (the command line's checks before a run).
"""

import importlib

_BOOK_CONSTANTS = (
    "BOOK_CURRENT_BANDWIDTH",
    "BOOK_SPEED_BANDWIDTH",
    "BOOK_CURRENT_LIMIT",
    "BOOK_DC_LINK",
    "BOOK_TS",
)
_THREE_PHASE = (
    "PR_W_C",
    "book_motor",
    "MOTORS",
    "make_machine",
    "book_drive",
    "smc_drive",
    "HYSTERESIS_BAND_A",
    "HYSTERESIS_SAMPLE_PERIOD_S",
    "HYSTERESIS_SPEED_PERIOD_S",
    "hysteresis_drive",
    "field_weakening_drive",
    "field_weakening_block",
    "pr_drive",
    "sensorless_drive",
    "with_observer",
    "STARTUP_DEFAULTS",
    "book_scenario",
    "load_motor",
    "DTC_SAMPLE_PERIOD_S",
    "DTC_TORQUE_BAND_NM",
    "DTC_FLUX_BAND_WB",
    "DTC_SPEED_PERIOD_S",
    "FLUX_OBSERVER_CROSSOVER",
    "dtc_drive",
    "smc_dtc_drive",
)
#: Public name -> (module, attribute), the layout of ``pmsmjax._LAZY``.
_LAZY = {
    **{name: ("book_constants", name) for name in _BOOK_CONSTANTS},
    **{name: ("three_phase", name) for name in _THREE_PHASE},
}

__all__ = [*_BOOK_CONSTANTS, *_THREE_PHASE]


def __getattr__(name):
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    module, attr = _LAZY[name]
    value = getattr(importlib.import_module(f"{__name__}.{module}"), attr)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY))
