"""Plant models: the three-phase PMSM in its three frames, the n-phase (six-phase) PMSM in its frames,
their parameters and integrators."""

from pmsmjax.machines.base import AbstractMachine, MachineInput, MachineState
from pmsmjax.machines.continuous import linearise, solve_adaptive
from pmsmjax.machines.integrate import advance, rk4_step
from pmsmjax.machines.motor import PMSMParameters
from pmsmjax.machines.multiphase_motor import MultiPhaseParameters
from pmsmjax.machines.pmsm3 import PMSMabc, PMSMAlphaBeta, PMSMdq
from pmsmjax.machines.pmsm6 import PMSM6DoubleDQ
from pmsmjax.machines.pmsm_multiphase import (
    AbstractMultiPhaseMachine,
    MultiPhasePMSMdq,
    MultiPhasePMSMNatural,
    MultiPhasePMSMVSD,
)
from pmsmjax.machines.saturation import DAxisSaturation, SaturatedPMSMdq, saturated_machine

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
