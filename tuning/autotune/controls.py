"""What ``pmsmjax tune --control NAME`` tunes for each control method, and on which surrogate.

Per control ([`pmsmjax.presets.control_methods.CONTROLS`][pmsmjax.presets.control_methods.CONTROLS]):

- the gains tuned by default (dotted names or the aliases of `tuning.parameters.ALIASES`):
  PI: the speed and current PIs; SMC: the surface and reaching-law gains ``c, eps, q`` and the current
  PIs; PR: the resonant current controller's ``kp, kr, w_c``; SMC-DTC: the speed PI and the sliding-mode
  DTC's switching gains and boundary layers ``K_T, phi_T, K_psi, phi_psi``;
- the preset options of the *surrogate* the optimiser differentiates: the SMC's ``sign`` switching has a
  zero derivative almost everywhere, so it is tuned with ``tanh`` (its boundary layer from the design rule)
  and the tuned gains are re-evaluated on the exact ``sign`` law (both figures reported); the SMC-DTC
  likewise with ``tanh`` for its ``saturation`` law (continuous, but with kinks at the layer's edges); the
  others are smooth already;
- the objective weights used when the job is given none (the SMC-DTC adds torque ripple, per N m RMS over
  each scenario's last 20 %, to the speed ITAE: a narrow boundary layer that tightens the torque loop
  makes the surrogate chatter at the PWM rate, and the ripple term is what prices that).
"""

import dataclasses

from pmsmjax.spec.validation import ParameterError


@dataclasses.dataclass(frozen=True)
class ControlTuning:
    """`names`: the gains tuned by default; `surrogate`: preset options of the differentiated drive;
    `weights`: [`ObjectiveWeights`][tuning.autotune.objectives.ObjectiveWeights] fields that differ from its
    defaults when the job is given no weights."""

    names: tuple[str, ...]
    surrogate: dict = dataclasses.field(default_factory=dict)
    weights: dict = dataclasses.field(default_factory=dict)


#: Weight of the torque ripple (per N m RMS) in the SMC-DTC's default objective: the ripple of the design-rule
#: gains (0.01-0.2 N m over the last 20 % of a batch scenario, mostly the speed loop's settling) then
#: weighs a tenth of the speed ITAE (0.03-0.3 rad s), and a chattering law (1 N m with the sign
#: function) as much as the ITAE itself.
SMC_DTC_RIPPLE_WEIGHT = 0.1

TUNABLE_CONTROLS = {
    "pi": ControlTuning(("speed", "current")),
    "smc": ControlTuning(("smc", "current"), {"switching": "tanh"}),
    "pr": ControlTuning(("pr",)),
    "smc-dtc": ControlTuning(
        ("speed", "smc_dtc"), {"switching": "tanh"}, {"torque_ripple": SMC_DTC_RIPPLE_WEIGHT}
    ),
}


_VSD_DQ = tuple(f"controller.current.dq.{k}" for k in ("kp_d", "kp_q", "ki_d", "ki_q"))
_PR_DQ = tuple(f"controller.current.dq.{k}" for k in ("kp", "kr", "w_c"))

#: The six-phase schemes
#: ([`pmsmjax.presets.six_phase.SIX_PHASE_CONTROLS`][pmsmjax.presets.six_phase.SIX_PHASE_CONTROLS]): the speed
#: PI and the fundamental-subspace current gains (double dq: its four PIs and the cross-coupling
#: compensation). The z1-z2 gains are left out by default: on the balanced nominal plant with the averaged
#: bridge no z1-z2 current flows, so the speed objectives give them no gradient (name them, e.g.
#: ``controller.current.z.kp``, to tune them on an unbalanced plant).
SIX_PHASE_TUNABLE_CONTROLS = {
    "vsd": ControlTuning(("speed",) + _VSD_DQ),
    "conventional": ControlTuning(("speed",) + _VSD_DQ),
    "double-dq": ControlTuning(("speed", "current", "controller.current.kc_d", "controller.current.kc_q")),
    "pr": ControlTuning(("speed",) + _PR_DQ),
}


#: The five-phase schemes
#: ([`pmsmjax.presets.five_phase.FIVE_PHASE_CONTROLS`][pmsmjax.presets.five_phase.FIVE_PHASE_CONTROLS]): the
#: speed PI and the dq current gains (the x-y gains left out as the six-phase z1-z2 ones, for the same
#: reason).
FIVE_PHASE_TUNABLE_CONTROLS = {
    "vsd": ControlTuning(("speed",) + _VSD_DQ),
    "conventional": ControlTuning(("speed",) + _VSD_DQ),
    "pr": ControlTuning(("speed",) + _PR_DQ),
}


def control_tuning(name: str, machine: str = "three-phase") -> ControlTuning:
    """The default tuning job of control `name` on `machine` (``three-phase``, ``six-phase`` or
    ``five-phase``); [`ParameterError`][pmsmjax.spec.validation.ParameterError] listing the tunable controls
    for another name."""
    table = {"six-phase": SIX_PHASE_TUNABLE_CONTROLS, "five-phase": FIVE_PHASE_TUNABLE_CONTROLS}.get(
        machine, TUNABLE_CONTROLS
    )
    if name not in table:
        raise ParameterError(f"pmsmjax tune tunes the {machine} controls {', '.join(table)}, not {name!r}.")
    return table[name]
