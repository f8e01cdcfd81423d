"""Modulators and inverter bridge models (three-phase; six-phase modulators and n-leg bridges)."""

from pmsmjax.inverters.averaged import AveragedBridge, phase_voltages
from pmsmjax.inverters.base import AbstractBridge, AbstractModulator
from pmsmjax.inverters.multiphase_bridges import MultiPhaseAveragedBridge, MultiPhaseSwitchingBridge
from pmsmjax.inverters.multiphase_carrier import ZeroSequencePWM
from pmsmjax.inverters.multiphase_svpwm import LargeVectorSVPWM, NearFourVectorSVPWM
from pmsmjax.inverters.six_phase_carrier import DecoupledSVPWM, DoubleZeroSequencePWM
from pmsmjax.inverters.six_phase_svpwm import FourVectorSVPWM, TwoVectorSVPWM
from pmsmjax.inverters.spwm import MinMaxPWM, SinusoidalPWM, ThirdHarmonicPWM, third_harmonic
from pmsmjax.inverters.svpwm import SVPWM, sector_code, switching_times
from pmsmjax.inverters.switching import SwitchingBridge

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
