"""The former name of :mod:`pmsmjax.controllers.multiphase` (its controllers serve five phases as well as
six), kept importable because the documentation (chapter 7) and the six- and five-phase presets still
name it; ``SixPhaseFOC`` is :class:`~pmsmjax.controllers.multiphase.MultiPhaseFOC`."""

from pmsmjax.controllers.multiphase import (
    AbstractMultiPhaseCurrentController,
    AbstractZCurrentController,
    DoubleDQCurrentPI,
    MultiPhaseFOC,
    VSDCurrentControl,
    ZCurrentPI,
    ZProportionalResonant,
    double_dq_design,
    pr_current_design,
    vsd_current_design,
    z_current_imc,
    z_pr_design,
)

SixPhaseFOC = MultiPhaseFOC

__all__ = [
    "AbstractMultiPhaseCurrentController",
    "AbstractZCurrentController",
    "DoubleDQCurrentPI",
    "MultiPhaseFOC",
    "VSDCurrentControl",
    "ZCurrentPI",
    "ZProportionalResonant",
    "double_dq_design",
    "pr_current_design",
    "vsd_current_design",
    "z_current_imc",
    "z_pr_design",
    "SixPhaseFOC",
]
