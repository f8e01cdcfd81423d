"""Modulators and inverter bridge models."""

from .averaged import AveragedBridge, phase_voltages
from .base import AbstractBridge, AbstractModulator
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
]
