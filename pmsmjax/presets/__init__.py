"""Ready-made drives: the book's constants ([`book_constants`][pmsmjax.presets.book_constants]), the book's
three-phase drive ([`three_phase`][pmsmjax.presets.three_phase], re-exported here), the six- and five-phase
drives ([`six_phase`][pmsmjax.presets.six_phase], [`five_phase`][pmsmjax.presets.five_phase]), the control
methods by name ([`control_methods`][pmsmjax.presets.control_methods]) and the motor files in ``motors/``.

The re-exported names are imported on first use (PEP 562), so that ``pmsmjax.presets.book_constants``
reads without loading JAX (the command line's checks before a run).
"""

from pmsmjax._lazy import by_module, lazy_exports

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
#: Sensorless drives are assembled ([`pmsmjax.assemble`][pmsmjax.assemble]); their names stay here, where
#: users find the book's drives.
_ASSEMBLED = ("sensorless_drive", "with_observer", "STARTUP_DEFAULTS")
#: Public name -> (module, attribute), the layout of ``pmsmjax._LAZY``.
_LAZY = by_module({"book_constants": _BOOK_CONSTANTS, "three_phase": _THREE_PHASE, "..assemble": _ASSEMBLED})

__all__ = list(_LAZY)


__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
