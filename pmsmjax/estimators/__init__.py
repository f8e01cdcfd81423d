"""Estimators: the block between sampling and control that gives the rotor angle and speed.

Position sensors (:class:`ExactSensor`, :class:`Encoder`) today; the observers of chapters 5-6 implement
the same :class:`AbstractEstimator` interface.
"""

from .base import AbstractEstimator
from .flux_observer import StatorFluxObserver, StatorFluxObserverState
from .position_sensors import Encoder, EncoderState, ExactSensor

__all__ = [
    "AbstractEstimator",
    "Encoder",
    "EncoderState",
    "ExactSensor",
    "StatorFluxObserver",
    "StatorFluxObserverState",
]
