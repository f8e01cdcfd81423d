"""Plant models: the three-phase PMSM in its three frames, the n-phase (six-phase) PMSM in its frames,
their parameters and integrators.

The re-exported names are imported on first use (PEP 562), so that the plain-array modules here (the
steady-state dq equations, [`dq_equations`][pmsmjax.machines.dq_equations]; the flux map's grid and
interpolant, [`flux_map`][pmsmjax.machines.flux_map]) read without loading JAX: the command line's checks
before a run use them.
"""

from pmsmjax._lazy import by_module, lazy_exports

#: Module -> the names re-exported from it; ``_LAZY``: name -> (module, name), the layout of
#: ``pmsmjax._LAZY``.
_LAZY = by_module({
    "base": ("AbstractMachine", "MachineInput", "MachineState"),
    "motor": ("PMSMParameters",),
    "pmsm3": ("PMSMabc", "PMSMAlphaBeta", "PMSMdq"),
    "integrate": ("advance", "rk4_step"),
    "continuous": ("linearise", "solve_adaptive"),
    "pmsm_multiphase": (
        "AbstractMultiPhaseMachine", "MultiPhasePMSMdq", "MultiPhasePMSMVSD",
    ),
    "pmsm_multiphase_natural": ("MultiPhasePMSMNatural",),
    "multiphase_motor": ("MultiPhaseParameters",),
    "pmsm6": ("PMSM6DoubleDQ",),
    "saturation": ("DAxisSaturation", "SaturatedPMSMdq", "saturated_machine"),
})  # fmt: skip

__all__ = list(_LAZY)


__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
