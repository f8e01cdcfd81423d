"""What ``pmsmjax tune --control NAME`` tunes for each control method, and on which surrogate.

Per control (:data:`pmsmjax.controls.CONTROLS`):

- the gains tuned by default (dotted names or the aliases of :data:`tuning.parameters.ALIASES`):
  PI: the speed and current PIs; SMC: the surface and reaching-law gains ``c, eps, q`` and the current
  PIs; PR: the resonant current controller's ``kp, kr, w_c``;
- the preset options of the *surrogate* the optimiser differentiates: the SMC's ``sign`` switching has a
  zero derivative almost everywhere, so it is tuned with ``tanh`` (its boundary layer from the design rule)
  and the tuned gains are re-evaluated on the exact ``sign`` law (DESIGN.md, "Gradients"); the others are
  smooth already.
"""

import dataclasses

from pmsmjax.validation import ParameterError


@dataclasses.dataclass(frozen=True)
class ControlTuning:
    """`names`: the gains tuned by default; `surrogate`: preset options of the differentiated drive."""

    names: tuple[str, ...]
    surrogate: dict = dataclasses.field(default_factory=dict)


TUNABLE_CONTROLS = {
    "pi": ControlTuning(("speed", "current")),
    "smc": ControlTuning(("smc", "current"), {"switching": "tanh"}),
    "pr": ControlTuning(("pr",)),
}


def control_tuning(name: str) -> ControlTuning:
    if name not in TUNABLE_CONTROLS:
        raise ParameterError(f"pmsmjax tune tunes the controls {', '.join(TUNABLE_CONTROLS)}, not {name!r}.")
    return TUNABLE_CONTROLS[name]
