"""The registry of methods (pmsmjax/spec/registry.py) against what it names: every factory exists, the
options it declares are exactly the keyword options the factory takes, the multi-phase modulator and frame
tables of the presets hold exactly its names, and reading it loads no JAX."""

import functools
import inspect
import subprocess
import sys

import pytest

from pmsmjax.spec import registry
from pmsmjax.spec.validation import ParameterError

WITH_FACTORY = [m for m in registry.REGISTRY if m.factory]


@pytest.mark.parametrize("entry", WITH_FACTORY, ids=lambda m: f"{m.kind}:{m.name}:{m.machines[0]}")
def test_declared_options_are_the_factorys_keyword_options(entry):
    factory = registry.load_factory(entry)
    fixed = dict(entry.fixed)
    if fixed:
        factory = functools.partial(factory, **fixed)
    params = inspect.signature(factory).parameters
    keyword = [p for p, v in params.items() if v.kind == v.KEYWORD_ONLY and p not in fixed]
    if entry.kind in ("modulator", "frame"):
        assert entry.options == ()
        return
    if any(v.kind == v.VAR_KEYWORD for v in params.values()):  # a preset passing the rest to book_drive
        keyword += [p for p in registry.method("control", "pi").options if p not in keyword]
    assert sorted(entry.options) == sorted(keyword) and len(set(entry.options)) == len(entry.options)


def test_multiphase_tables_hold_the_registry_names():
    from pmsmjax.presets import five_phase, six_phase

    assert tuple(six_phase.SIX_PHASE_PWMS) == registry.names("modulator", "six-phase")
    assert tuple(five_phase.FIVE_PHASE_PWMS) == registry.names("modulator", "five-phase")
    assert tuple(six_phase.SIX_PHASE_FRAMES) == registry.names("frame", "six-phase")
    assert tuple(five_phase.FIVE_PHASE_FRAMES) == registry.names("frame", "five-phase")
    for machine, table in (
        ("six-phase", six_phase.SIX_PHASE_PWMS),
        ("five-phase", five_phase.FIVE_PHASE_PWMS),
    ):
        for name in table:
            assert registry.load_factory(registry.method("modulator", name, machine)) is table[name]


def test_every_estimator_of_the_catalogue_is_registered_once():
    from pmsmjax.estimators.registry import _EVERY

    assert tuple(_EVERY) == registry.names("estimator")


def test_names_and_defaults_per_machine():
    assert registry.names("control") == ("pi", "smc", "pr", "hysteresis", "dtc", "smc-dtc")
    assert registry.names("control", "six-phase") == ("vsd", "double-dq", "conventional", "pr")
    assert registry.names("control", "five-phase") == ("vsd", "conventional", "pr")
    assert registry.names("control", group="foc") == ("pi", "smc", "pr")
    assert registry.default("control") == "pi"
    assert registry.default("control", "five-phase") == "vsd"
    assert registry.default("modulator", "six-phase") == "four-vector"


def test_refusals_name_the_machine_or_the_closest_name():
    with pytest.raises(ParameterError, match="runs on the six-phase machine"):
        registry.method("control", "double-dq")
    with pytest.raises(ParameterError, match=r"did you mean 'smc-dtc'"):
        registry.method("control", "smc_dtc")
    with pytest.raises(ParameterError, match="do not apply to control 'pi'; it takes frame"):
        registry.check_options(registry.method("control", "pi"), {"band_a": 1.0})


def test_reading_the_registry_loads_no_jax():
    code = (
        "import sys; from pmsmjax.spec import registry; registry.names('estimator'); "
        "registry.method('control', 'pi'); print('jax' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
