"""Estimators: the block between sampling and control that gives the rotor angle and speed.

Position sensors ([`ExactSensor`][pmsmjax.estimators.position_sensors.ExactSensor],
[`Encoder`][pmsmjax.estimators.position_sensors.Encoder]) and the phase-current sensors the drive samples
through ([`CurrentSensors`][pmsmjax.estimators.current_sensors.CurrentSensors]: offset, gain, ADC step), the
stator flux observer of direct torque control
([`StatorFluxObserver`][pmsmjax.estimators.flux_observer.StatorFluxObserver], chapter 4) and the
fundamental-model observers of chapter 5 ([`OBSERVERS`][pmsmjax.estimators.catalogue.OBSERVERS]: ``smo``,
``smo-pll``, ``adaptive-smo``, ``dq-smo``, ``mras``, ``ekf``), all implementing
[`AbstractEstimator`][pmsmjax.estimators.base.AbstractEstimator];
[`StartupEstimator`][pmsmjax.estimators.startup.StartupEstimator] wraps an observer in the I/f start from
standstill; [`make_observer`][pmsmjax.estimators.registry.make_observer] builds an observer by name with its
design rule. The HF-injection estimators of chapter 6
([`HFIRotating`][pmsmjax.estimators.hfi_rotating.HFIRotating],
[`HFIPulsating`][pmsmjax.estimators.hfi_pulsating.HFIPulsating]; ``hfi-rotating``, ``hfi-pulsating``) read the
saliency at standstill and low speed. On a saturated machine given by a flux map,
[`cross_saturation_compensated`][pmsmjax.estimators.hfi_cross_saturation.cross_saturation_compensated] takes
the map's cross-saturation angle out of HF injection and
[`map_scheduled`][pmsmjax.estimators.map_scheduled.map_scheduled] gives a fundamental-model observer the map's
model at the operating current and
[`map_angle_corrected`][pmsmjax.estimators.map_angle_corrected.map_angle_corrected] keeps its constant model
and takes the map's steady angle error out (the one that runs the closed loop cleanly);
[`MapFluxObserver`][pmsmjax.estimators.map_flux_observer.MapFluxObserver] (``flux-observer``) estimates the
stator flux on the current-flux relation itself (the map, or the linear model) and reads the angle from the
flux mismatch.
"""

from pmsmjax.estimators.adaptive_smo import AdaptiveSMO, adaptive_smo_design
from pmsmjax.estimators.base import AbstractEstimator
from pmsmjax.estimators.current_sensors import AbstractCurrentSensor, CurrentSensors, IdealCurrentSensor
from pmsmjax.estimators.dq_smo import DQSlidingModeObserver, dq_smo_design
from pmsmjax.estimators.ekf import EKF, ekf_design
from pmsmjax.estimators.flux_observer import StatorFluxObserver, StatorFluxObserverState
from pmsmjax.estimators.hfi_cross_saturation import CrossSaturationCompensated, cross_saturation_compensated
from pmsmjax.estimators.hfi_pulsating import HFIPulsating, hfi_pulsating_design
from pmsmjax.estimators.hfi_rotating import HFIRotating, hfi_rotating_design
from pmsmjax.estimators.hybrid import HybridEstimator, HybridState, hybrid_design
from pmsmjax.estimators.map_angle_corrected import MapAngleCorrected, map_angle_corrected
from pmsmjax.estimators.map_flux_observer import MapFluxObserver, MapFluxObserverState, flux_observer_design
from pmsmjax.estimators.map_scheduled import MapScheduled, map_scheduled
from pmsmjax.estimators.mras import MRAS, mras_design
from pmsmjax.estimators.pll import PLL, pll_design
from pmsmjax.estimators.polarity import PolarityDetector, PolarityState, polarity_detector
from pmsmjax.estimators.position_sensors import Encoder, EncoderState, ExactSensor
from pmsmjax.estimators.registry import (
    HYBRID_OBSERVERS,
    INJECTION_OBSERVERS,
    OBSERVERS,
    make_observer,
    observer_options,
)
from pmsmjax.estimators.smo import SlidingModeObserver, smo_design
from pmsmjax.estimators.startup import StartupEstimator, StartupState

__all__ = [
    "EKF",
    "HFIPulsating",
    "INJECTION_OBSERVERS",
    "HYBRID_OBSERVERS",
    "HFIRotating",
    "MRAS",
    "OBSERVERS",
    "PLL",
    "AbstractCurrentSensor",
    "AbstractEstimator",
    "CurrentSensors",
    "IdealCurrentSensor",
    "AdaptiveSMO",
    "DQSlidingModeObserver",
    "Encoder",
    "EncoderState",
    "ExactSensor",
    "SlidingModeObserver",
    "StartupEstimator",
    "StartupState",
    "StatorFluxObserver",
    "StatorFluxObserverState",
    "adaptive_smo_design",
    "dq_smo_design",
    "ekf_design",
    "hfi_pulsating_design",
    "hfi_rotating_design",
    "make_observer",
    "mras_design",
    "observer_options",
    "pll_design",
    "smo_design",
    "PolarityDetector",
    "PolarityState",
    "polarity_detector",
    "HybridEstimator",
    "HybridState",
    "hybrid_design",
    "CrossSaturationCompensated",
    "cross_saturation_compensated",
    "MapAngleCorrected",
    "map_angle_corrected",
    "MapScheduled",
    "map_scheduled",
    "MapFluxObserver",
    "MapFluxObserverState",
    "flux_observer_design",
]
