"""Observers by name: the one registry behind ``pmsmjax observe --observer``, :func:`pmsmjax.presets.
sensorless_drive` and the chapter 5 workflows (tuning, Monte Carlo, comparison).

Each name maps to the design rule that builds the observer from a motor and the control period; options
are the design rule's keyword arguments (e.g. ``switching="sign"``, ``pll_bandwidth=500.0``,
``model=...`` for an observer whose motor model differs from the plant's). The HF-injection estimators
(chapter 6: ``hfi-rotating``, ``hfi-pulsating``; :data:`INJECTION_OBSERVERS`, looked up by the same
functions) take ``hf_voltage`` (V) and
``hf_frequency`` (Hz) among their options. The whole-speed-range ``hybrid`` (:data:`HYBRID_OBSERVERS`,
:mod:`.hybrid`) takes its band, its two parts' names and their options.
"""

import difflib
import functools
import inspect

from pmsmjax.checks.validation import ParameterError
from pmsmjax.estimators.adaptive_smo import adaptive_smo_design
from pmsmjax.estimators.base import AbstractEstimator
from pmsmjax.estimators.dq_smo import dq_smo_design
from pmsmjax.estimators.ekf import ekf_design
from pmsmjax.estimators.hfi_pulsating import hfi_pulsating_design
from pmsmjax.estimators.hfi_rotating import hfi_rotating_design
from pmsmjax.estimators.hybrid import hybrid_design
from pmsmjax.estimators.mras import mras_design
from pmsmjax.estimators.smo import smo_design
from pmsmjax.machines.motor import PMSMParameters

#: Observer name -> (design rule ``f(motor, Ts, **options)``, one-line description).
OBSERVERS = {
    "smo": (
        functools.partial(smo_design, angle="arctan"),
        "classic SMO in alpha-beta, sigmoid switching, back-EMF low-pass, arctan + exact lag compensation",
    ),
    "smo-pll": (
        functools.partial(smo_design, angle="pll"),
        "classic SMO in alpha-beta, sigmoid switching, back-EMF low-pass, PLL + exact lag compensation",
    ),
    "adaptive-smo": (
        adaptive_smo_design,
        "SMO with an adaptive back-EMF model (speed adaptation, no low-pass)",
    ),
    "dq-smo": (
        dq_smo_design,
        "SMO in the estimated rotating frame on the extended EMF, PLL on E_d (salient)",
    ),
    "mras": (mras_design, "MRAS: current model as adjustable model, Popov PI speed adaptation"),
    "ekf": (ekf_design, "extended Kalman filter, state [i_alpha, i_beta, w_e, theta_e]"),
}

#: The HF-injection estimators of chapter 6, same form. Kept apart from :data:`OBSERVERS` (the chapter 5
#: fundamental-model observers, which the chapter 5 studies, benchmarks and ``demo --estimator`` iterate
#: over on the surface book motor): these need a salient machine and give the d axis modulo pi.
INJECTION_OBSERVERS = {
    "hfi-rotating": (
        hfi_rotating_design,
        "rotating HF injection (salient machines, standstill and low speed; angle modulo pi)",
    ),
    "hfi-pulsating": (
        hfi_pulsating_design,
        "pulsating HF injection on the estimated d axis (salient machines; angle modulo pi)",
    ),
}

#: Whole-speed-range estimators (chapter 6 with chapter 5), same form; apart from
#: :data:`INJECTION_OBSERVERS` because they are no modulo-pi injection estimators (studies of those
#: iterate over that registry), though they inject a carrier at low speed.
HYBRID_OBSERVERS = {
    "hybrid": (
        hybrid_design,
        "HF injection (with start-up polarity pulses) below a crossover band, EKF above: whole speed range",
    ),
}


def _registered(name: str):
    for registry in (OBSERVERS, INJECTION_OBSERVERS):
        if name in registry:
            return registry[name]
    return HYBRID_OBSERVERS[name]


def observer_options(name: str) -> tuple[str, ...]:
    """Keyword options the design rule of observer ``name`` accepts."""
    rule = _registered(name)[0]
    fixed = rule.keywords if isinstance(rule, functools.partial) else {}
    params = inspect.signature(rule).parameters
    return tuple(p for p, v in params.items() if v.kind == v.KEYWORD_ONLY and p not in fixed)


def check_observer_name(name: str) -> None:
    """Refuse an unknown observer name, with the closest known name as a hint."""
    known = [*OBSERVERS, *INJECTION_OBSERVERS, *HYBRID_OBSERVERS]
    if name not in known:
        close = difflib.get_close_matches(name, known, n=1, cutoff=0.5)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise ParameterError(f"unknown observer {name!r}{hint}: choose from {', '.join(known)}.")


def make_observer(name: str, motor: PMSMParameters, Ts: float, **options) -> AbstractEstimator:
    """The observer ``name`` for ``motor`` at control period ``Ts`` (s), design-rule gains unless
    ``options`` override them; its gains are checked at ``Ts`` (unstable ones are refused)."""
    check_observer_name(name)
    allowed = observer_options(name)
    bad = sorted(set(options) - set(allowed))
    if bad:
        raise ParameterError(
            f"option(s) {', '.join(bad)} do not apply to observer {name!r}; it takes {', '.join(allowed)}."
        )
    observer = _registered(name)[0](motor, Ts, **options)
    observer.check_period(Ts)
    return observer
