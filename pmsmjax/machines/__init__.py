"""Plant models: the three-phase PMSM in its three frames, the n-phase (six-phase) PMSM in its frames,
their parameters and integrators.

The re-exported names are imported on first use (PEP 562), so that the plain-array modules here (the
steady-state dq equations, :mod:`.dq_equations`; the flux map's grid and interpolant,
:mod:`.flux_map`) read without loading JAX: the command line's checks before a run use them.
"""

from pmsmjax._lazy import lazy_exports

#: Public name -> (module, attribute), the layout of ``pmsmjax._LAZY``.
_LAZY = {
    "AbstractMachine": ("base", "AbstractMachine"),
    "MachineInput": ("base", "MachineInput"),
    "MachineState": ("base", "MachineState"),
    "PMSMParameters": ("motor", "PMSMParameters"),
    "PMSMabc": ("pmsm3", "PMSMabc"),
    "PMSMAlphaBeta": ("pmsm3", "PMSMAlphaBeta"),
    "PMSMdq": ("pmsm3", "PMSMdq"),
    "advance": ("integrate", "advance"),
    "linearise": ("continuous", "linearise"),
    "solve_adaptive": ("continuous", "solve_adaptive"),
    "rk4_step": ("integrate", "rk4_step"),
    "AbstractMultiPhaseMachine": ("pmsm_multiphase", "AbstractMultiPhaseMachine"),
    "MultiPhaseParameters": ("multiphase_motor", "MultiPhaseParameters"),
    "MultiPhasePMSMdq": ("pmsm_multiphase", "MultiPhasePMSMdq"),
    "MultiPhasePMSMNatural": ("pmsm_multiphase", "MultiPhasePMSMNatural"),
    "MultiPhasePMSMVSD": ("pmsm_multiphase", "MultiPhasePMSMVSD"),
    "PMSM6DoubleDQ": ("pmsm6", "PMSM6DoubleDQ"),
    "DAxisSaturation": ("saturation", "DAxisSaturation"),
    "SaturatedPMSMdq": ("saturation", "SaturatedPMSMdq"),
    "saturated_machine": ("saturation", "saturated_machine"),
}

__all__ = list(_LAZY)


__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
