"""Modulators and inverter bridge models."""

from .averaged import AveragedBridge, phase_voltages
from .base import AbstractBridge, AbstractModulator
from .svpwm import SVPWM, sector_code, switching_times

__all__ = [
    "AbstractBridge",
    "AbstractModulator",
    "AveragedBridge",
    "SVPWM",
    "phase_voltages",
    "sector_code",
    "switching_times",
]
