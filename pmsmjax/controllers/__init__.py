"""Controllers: the controller interfaces, discrete PI, design rules, cascaded FOC with its blocks (PI and
sliding-mode speed loops; dq PI or proportional-resonant current loops; MTPA and field weakening), and
hysteresis current control; switching-table and sliding-mode direct torque control; the six- and
five-phase cascade (VSD, double dq, PR current loops).

The re-exported names are imported on first use (PEP 562), so that the plain-NumPy modules here (the
flux map's MTPA and MTPV tables, [`flux_map_loci`][pmsmjax.controllers.flux_map_loci]) read without loading
JAX: the drive file's checks before a run build an MTPA table.
"""

from pmsmjax._lazy import by_module, lazy_exports

#: Module -> the names re-exported from it; ``_LAZY``: name -> (module, name), the layout of
#: ``pmsmjax._LAZY``.
_LAZY = by_module({
    "foc": ("FOC", "FOCState"),
    "hysteresis": ("HysteresisCurrentControl", "HysteresisState", "hysteresis_comparator"),
    "mtpa": ("MTPA", "mtpa_id_from_iq", "mtpa_id_from_magnitude"),
    "field_weakening": ("VoltageFeedbackFieldWeakening",),
    "base": (
        "AbstractController", "AbstractCurrentController", "AbstractDAxisReference",
        "AbstractSpeedController", "CurrentLoopContext",
    ),
    "design": (
        "CurrentLoopGains", "SpeedLoopGains", "current_loop_imc", "first_order_rise_time",
        "speed_loop_active_damping",
    ),
    "smc": ("SlidingModeSpeed", "SlidingModeState", "smc_design", "switching_function"),
    "pr": ("ProportionalResonant", "ResonantCoefficients", "pr_design", "resonant_coefficients"),
    "pi": ("clip_magnitude", "clip_symmetric", "pi_update", "realisable_reference_tracking"),
    "dtc": ("SwitchingTableDTC", "torque_current_limit"),
    "smc_dtc": ("SlidingModeDTC", "smc_dtc_design"),
    "multiphase": (
        "DoubleDQCurrentPI", "MultiPhaseFOC", "VSDCurrentControl", "ZCurrentPI", "ZProportionalResonant",
    ),
    "multiphase_design": (
        "double_dq_design", "pr_current_design", "vsd_current_design", "z_current_imc", "z_pr_design",
    ),
})  # fmt: skip

__all__ = list(_LAZY)


__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
