"""Estimators by name: the one registry behind ``pmsmjax observe --observer``,
[`pmsmjax.presets.sensorless_drive`][pmsmjax.assemble.sensorless_drive] and the chapter 5 and 6
workflows (tuning, Monte Carlo, comparison).

It joins the single estimators of [`catalogue`][pmsmjax.estimators.catalogue]
([`OBSERVERS`][pmsmjax.estimators.catalogue.OBSERVERS], chapter 5; the HF-injection estimators
[`INJECTION_OBSERVERS`][pmsmjax.estimators.catalogue.INJECTION_OBSERVERS], chapter 6, whose options include
``hf_voltage`` (V) and ``hf_frequency`` (Hz)) with the whole-speed-range ``hybrid``
([`HYBRID_OBSERVERS`][pmsmjax.estimators.registry.HYBRID_OBSERVERS], [`hybrid`][pmsmjax.estimators.hybrid]),
which takes its band, its two parts' names and their options.
"""

from pmsmjax.estimators.base import AbstractEstimator
from pmsmjax.estimators.catalogue import INJECTION_OBSERVERS, OBSERVERS, build, check_name, options_of
from pmsmjax.estimators.hybrid import hybrid_design
from pmsmjax.machines.motor import PMSMParameters
from pmsmjax.spec.registry import method

__all__ = [
    "HYBRID_OBSERVERS",
    "INJECTION_OBSERVERS",
    "OBSERVERS",
    "check_observer_name",
    "make_observer",
    "observer_options",
]

#: Whole-speed-range estimators (chapter 6 with chapter 5), same form as
#: [`OBSERVERS`][pmsmjax.estimators.catalogue.OBSERVERS]; apart from
#: [`INJECTION_OBSERVERS`][pmsmjax.estimators.catalogue.INJECTION_OBSERVERS] because they are no modulo-pi
#: injection estimators (studies of those iterate over that registry), though they inject a carrier at low
#: speed.
HYBRID_OBSERVERS = {"hybrid": (hybrid_design, method("estimator", "hybrid").description)}

#: Every name, in the order a refusal lists them.
_EVERY = {**OBSERVERS, **INJECTION_OBSERVERS, **HYBRID_OBSERVERS}


def observer_options(name: str) -> tuple[str, ...]:
    """Keyword options the design rule of observer ``name`` accepts."""
    return options_of(_EVERY, name)


def check_observer_name(name: str) -> None:
    """Refuse an unknown observer name, with the closest known name as a hint."""
    check_name(_EVERY, name)


def make_observer(name: str, motor: PMSMParameters, Ts: float, **options) -> AbstractEstimator:
    """The observer ``name`` for ``motor`` at control period ``Ts`` (s), design-rule gains unless
    ``options`` override them; its gains are checked at ``Ts`` (unstable ones are refused)."""
    return build(_EVERY, name, motor, Ts, **options)
