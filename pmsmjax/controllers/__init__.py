"""Controllers: the controller interfaces, discrete PI, design rules, cascaded FOC with its blocks (PI and
sliding-mode speed loops; dq PI or proportional-resonant current loops; MTPA and field weakening), and
hysteresis current control; switching-table and sliding-mode direct torque control; the six-phase
cascade (VSD, double dq, PR current loops).

The re-exported names are imported on first use (PEP 562), so that the plain-NumPy modules here (the
flux map's MTPA and MTPV tables, :mod:`.flux_map_loci`) read without loading JAX: the drive file's checks
before a run build an MTPA table.
"""

from pmsmjax._lazy import lazy_exports

#: Public name -> (module, attribute), the layout of ``pmsmjax._LAZY``.
_LAZY = {
    "FOC": ("foc", "FOC"),
    "FOCState": ("foc", "FOCState"),
    "HysteresisCurrentControl": ("hysteresis", "HysteresisCurrentControl"),
    "HysteresisState": ("hysteresis", "HysteresisState"),
    "MTPA": ("mtpa", "MTPA"),
    "VoltageFeedbackFieldWeakening": ("field_weakening", "VoltageFeedbackFieldWeakening"),
    "AbstractController": ("base", "AbstractController"),
    "AbstractCurrentController": ("base", "AbstractCurrentController"),
    "AbstractDAxisReference": ("base", "AbstractDAxisReference"),
    "AbstractSpeedController": ("base", "AbstractSpeedController"),
    "CurrentLoopContext": ("base", "CurrentLoopContext"),
    "CurrentLoopGains": ("design", "CurrentLoopGains"),
    "SlidingModeSpeed": ("smc", "SlidingModeSpeed"),
    "SlidingModeState": ("smc", "SlidingModeState"),
    "ProportionalResonant": ("pr", "ProportionalResonant"),
    "ResonantCoefficients": ("pr", "ResonantCoefficients"),
    "SpeedLoopGains": ("design", "SpeedLoopGains"),
    "clip_magnitude": ("pi", "clip_magnitude"),
    "clip_symmetric": ("pi", "clip_symmetric"),
    "current_loop_imc": ("design", "current_loop_imc"),
    "first_order_rise_time": ("design", "first_order_rise_time"),
    "hysteresis_comparator": ("hysteresis", "hysteresis_comparator"),
    "mtpa_id_from_iq": ("mtpa", "mtpa_id_from_iq"),
    "mtpa_id_from_magnitude": ("mtpa", "mtpa_id_from_magnitude"),
    "pi_update": ("pi", "pi_update"),
    "realisable_reference_tracking": ("pi", "realisable_reference_tracking"),
    "smc_design": ("smc", "smc_design"),
    "pr_design": ("pr", "pr_design"),
    "resonant_coefficients": ("pr", "resonant_coefficients"),
    "speed_loop_active_damping": ("design", "speed_loop_active_damping"),
    "switching_function": ("smc", "switching_function"),
    "SwitchingTableDTC": ("dtc", "SwitchingTableDTC"),
    "SlidingModeDTC": ("smc_dtc", "SlidingModeDTC"),
    "smc_dtc_design": ("smc_dtc", "smc_dtc_design"),
    "torque_current_limit": ("dtc", "torque_current_limit"),
    "DoubleDQCurrentPI": ("six_phase", "DoubleDQCurrentPI"),
    "SixPhaseFOC": ("six_phase", "SixPhaseFOC"),
    "MultiPhaseFOC": ("six_phase", "MultiPhaseFOC"),
    "VSDCurrentControl": ("six_phase", "VSDCurrentControl"),
    "ZCurrentPI": ("six_phase", "ZCurrentPI"),
    "ZProportionalResonant": ("six_phase", "ZProportionalResonant"),
    "double_dq_design": ("six_phase", "double_dq_design"),
    "pr_current_design": ("six_phase", "pr_current_design"),
    "vsd_current_design": ("six_phase", "vsd_current_design"),
    "z_current_imc": ("six_phase", "z_current_imc"),
    "z_pr_design": ("six_phase", "z_pr_design"),
}

__all__ = list(_LAZY)


__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
