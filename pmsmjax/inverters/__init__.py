"""Modulators and inverter bridge models: three-phase; n-phase modulators and n-leg bridges for any
[`PhaseLayout`][pmsmjax.frames.multiphase.PhaseLayout] (the six- and five-phase presets name them)."""

from pmsmjax.inverters.averaged import AveragedBridge, phase_voltages
from pmsmjax.inverters.base import AbstractBridge, AbstractModulator
from pmsmjax.inverters.decoupled_svpwm import DecoupledSVPWM
from pmsmjax.inverters.multiphase_bridges import MultiPhaseAveragedBridge, MultiPhaseSwitchingBridge
from pmsmjax.inverters.multiphase_carrier import ZeroSequencePWM
from pmsmjax.inverters.multiphase_svpwm import LargeVectorSVPWM, NearFourVectorSVPWM
from pmsmjax.inverters.spwm import MinMaxPWM, SinusoidalPWM, ThirdHarmonicPWM, third_harmonic
from pmsmjax.inverters.svpwm import SVPWM, sector_code, switching_times
from pmsmjax.inverters.switching import SwitchingBridge
from pmsmjax.inverters.voltage_error import VoltageError

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
    "LargeVectorSVPWM",
    "NearFourVectorSVPWM",
    "ZeroSequencePWM",
    "VoltageError",
]
