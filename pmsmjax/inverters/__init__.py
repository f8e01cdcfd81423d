"""Modulators and inverter bridge models (three-phase; six-phase modulators and n-leg bridges)."""

from .averaged import AveragedBridge, phase_voltages
from .base import AbstractBridge, AbstractModulator
from .multiphase_bridges import MultiPhaseAveragedBridge, MultiPhaseSwitchingBridge
from .multiphase_carrier import ZeroSequencePWM
from .multiphase_svpwm import LargeVectorSVPWM, NearFourVectorSVPWM
from .six_phase_carrier import DecoupledSVPWM, DoubleZeroSequencePWM
from .six_phase_svpwm import FourVectorSVPWM, TwoVectorSVPWM
from .spwm import MinMaxPWM, SinusoidalPWM, ThirdHarmonicPWM, third_harmonic
from .svpwm import SVPWM, sector_code, switching_times
from .switching import SwitchingBridge

__all__ = [
    "AbstractBridge",
    "AbstractModulator",
    "AveragedBridge",
    "MinMaxPWM",
    "SVPWM",
    "SinusoidalPWM",
    "SwitchingBridge",
    "ThirdHarmonicPWM",
    "phase_voltages",
    "sector_code",
    "switching_times",
    "third_harmonic",
    "MultiPhaseAveragedBridge",
    "MultiPhaseSwitchingBridge",
    "DecoupledSVPWM",
    "DoubleZeroSequencePWM",
    "FourVectorSVPWM",
    "TwoVectorSVPWM",
    "LargeVectorSVPWM",
    "NearFourVectorSVPWM",
    "ZeroSequencePWM",
]
