"""The single estimators by name: the chapter 5 observers
([`OBSERVERS`][pmsmjax.estimators.catalogue.OBSERVERS]) and the chapter 6 HF-injection estimators
([`INJECTION_OBSERVERS`][pmsmjax.estimators.catalogue.INJECTION_OBSERVERS]), and
[`build`][pmsmjax.estimators.catalogue.build], which makes one from a name table with its checks.

Each name maps to the design rule that builds the estimator from a motor and the control period; options
are the design rule's keyword arguments (e.g. ``switching="sign"``, ``pll_bandwidth=500.0``,
``model=...`` for an observer whose motor model differs from the plant's; ``hf_voltage`` (V) and
``hf_frequency`` (Hz) for the injection estimators). The estimators built from these (the whole-speed-range
hybrid, [`hybrid`][pmsmjax.estimators.hybrid]) and the registry of every name
([`registry`][pmsmjax.estimators.registry]) sit above this module.
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

#: The HF-injection estimators of chapter 6, same form. Kept apart from
#: [`OBSERVERS`][pmsmjax.estimators.catalogue.OBSERVERS] (the chapter 5 fundamental-model observers, which the
#: chapter 5 studies, benchmarks and ``demo --estimator`` iterate over on the surface book motor): these need
#: a salient machine and give the d axis modulo pi.
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


def options_of(table: dict, name: str) -> tuple[str, ...]:
    """Keyword options the design rule of ``name`` in ``table`` accepts."""
    rule = table[name][0]
    fixed = rule.keywords if isinstance(rule, functools.partial) else {}
    params = inspect.signature(rule).parameters
    return tuple(p for p, v in params.items() if v.kind == v.KEYWORD_ONLY and p not in fixed)


def check_name(table: dict, name: str, what: str = "observer") -> None:
    """Refuse a name ``table`` does not hold, with the closest known name as a hint."""
    if name not in table:
        close = difflib.get_close_matches(name, list(table), n=1, cutoff=0.5)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise ParameterError(f"unknown {what} {name!r}{hint}: choose from {', '.join(table)}.")


def build(
    table: dict, name: str, motor: PMSMParameters, Ts: float, what: str = "observer", **options
) -> AbstractEstimator:
    """The estimator ``name`` of ``table`` for ``motor`` at control period ``Ts`` (s), design-rule gains
    unless ``options`` override them; its gains are checked at ``Ts`` (unstable ones are refused)."""
    check_name(table, name, what)
    allowed = options_of(table, name)
    bad = sorted(set(options) - set(allowed))
    if bad:
        raise ParameterError(
            f"option(s) {', '.join(bad)} do not apply to {what} {name!r}; it takes {', '.join(allowed)}."
        )
    estimator = table[name][0](motor, Ts, **options)
    estimator.check_period(Ts)
    return estimator
