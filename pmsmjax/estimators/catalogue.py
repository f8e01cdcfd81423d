"""The single estimators by name: the chapter 5 observers
([`OBSERVERS`][pmsmjax.estimators.catalogue.OBSERVERS]) and the chapter 6 HF-injection estimators
([`INJECTION_OBSERVERS`][pmsmjax.estimators.catalogue.INJECTION_OBSERVERS]), and
[`build`][pmsmjax.estimators.catalogue.build], which makes one from a name table with its checks.

Each name maps to the design rule that builds the estimator from a motor and the control period; options
are the design rule's keyword arguments (e.g. ``switching="sign"``, ``pll_bandwidth=500.0``,
``model=...`` for an observer whose motor model differs from the plant's; ``hf_voltage`` (V) and
``hf_frequency`` (Hz) for the injection estimators). The estimators built from these (the whole-speed-range
hybrid, [`hybrid`][pmsmjax.estimators.hybrid]) and the estimators' registry
([`registry`][pmsmjax.estimators.registry]) sit above this module; names, descriptions and options are
[`pmsmjax.spec.registry`][pmsmjax.spec.registry]'s.
"""

import difflib
import functools

from pmsmjax.estimators.base import AbstractEstimator
from pmsmjax.machines.motor import PMSMParameters
from pmsmjax.spec.registry import REGISTRY, load_factory
from pmsmjax.spec.validation import ParameterError


def _design_rules(group: str) -> dict:
    """``{name: (design rule, description)}`` of the registry's estimators of ``group``."""
    table = {}
    for entry in REGISTRY:
        if entry.kind == "estimator" and entry.group == group:
            rule = load_factory(entry)
            table[entry.name] = (functools.partial(rule, **dict(entry.fixed)) if entry.fixed else rule,
                                 entry.description)  # fmt: skip
    return table


#: Observer name -> (design rule ``f(motor, Ts, **options)``, one-line description): the chapter 5
#: back-EMF observers of `pmsmjax.spec.registry.REGISTRY`.
OBSERVERS = _design_rules("observer")

#: The HF-injection estimators of chapter 6, same form. Kept apart from
#: [`OBSERVERS`][pmsmjax.estimators.catalogue.OBSERVERS] (the chapter 5 fundamental-model observers, which the
#: chapter 5 studies, benchmarks and ``demo --estimator`` iterate over on the surface book motor): these need
#: a salient machine and give the d axis modulo pi.
INJECTION_OBSERVERS = _design_rules("injection")


def options_of(table: dict, name: str) -> tuple[str, ...]:
    """Keyword options the design rule of ``name`` in ``table`` accepts (declared in the registry)."""
    check_name(table, name)
    return next(m.options for m in REGISTRY if m.kind == "estimator" and m.name == name)


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
