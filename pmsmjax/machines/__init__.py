"""Plant models: the three-phase PMSM in its three frames, its parameters and integrators."""

from .base import AbstractMachine, MachineInput, MachineState
from .continuous import linearise, solve_adaptive
from .integrate import advance, rk4_step
from .motor import PMSMParameters
from .pmsm3 import PMSMabc, PMSMAlphaBeta, PMSMdq
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
    "DAxisSaturation",
    "SaturatedPMSMdq",
    "saturated_machine",
]
