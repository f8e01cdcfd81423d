"""Plant models: the three-phase PMSM in its three frames, the n-phase (six-phase) PMSM in its frames,
their parameters and integrators."""

from .base import AbstractMachine, MachineInput, MachineState
from .continuous import linearise, solve_adaptive
from .integrate import advance, rk4_step
from .motor import PMSMParameters
from .multiphase_motor import MultiPhaseParameters
from .pmsm3 import PMSMabc, PMSMAlphaBeta, PMSMdq
from .pmsm6 import PMSM6DoubleDQ
from .pmsm_multiphase import (
    AbstractMultiPhaseMachine,
    MultiPhasePMSMdq,
    MultiPhasePMSMNatural,
    MultiPhasePMSMVSD,
)
from .saturation import DAxisSaturation, SaturatedPMSMdq, saturated_machine

__all__ = [
    "AbstractMachine",
    "MachineInput",
    "MachineState",
    "PMSMParameters",
    "PMSMabc",
    "PMSMAlphaBeta",
    "PMSMdq",
    "advance",
    "linearise",
    "solve_adaptive",
    "rk4_step",
    "AbstractMultiPhaseMachine",
    "MultiPhaseParameters",
    "MultiPhasePMSMdq",
    "MultiPhasePMSMNatural",
    "MultiPhasePMSMVSD",
    "PMSM6DoubleDQ",
    "DAxisSaturation",
    "SaturatedPMSMdq",
    "saturated_machine",
]
