"""The estimators by name (pmsmjax/estimators/catalogue.py): every name builds its design rule's estimator,
options reach the design rule, and a misspelt name or an option the rule does not take is refused in one
line naming it."""

import pytest

from pmsmjax import presets
from pmsmjax.estimators.catalogue import INJECTION_OBSERVERS, OBSERVERS, build, options_of
from pmsmjax.spec.validation import ParameterError

TS = 1e-4


@pytest.mark.parametrize(
    ("table", "name"),
    [(OBSERVERS, n) for n in OBSERVERS] + [(INJECTION_OBSERVERS, n) for n in INJECTION_OBSERVERS],
)
def test_every_name_builds_its_design_rule(table, name):
    motor = presets.book_motor(salient=table is INJECTION_OBSERVERS)
    built = build(table, name, motor, TS)
    expected = table[name][0](motor, TS)
    assert type(built) is type(expected)


def test_options_reach_the_design_rule():
    assert "switching" in options_of(OBSERVERS, "smo")
    assert "angle" not in options_of(OBSERVERS, "smo")  # fixed by the name (arctan or PLL)
    motor = presets.book_motor()
    assert build(OBSERVERS, "smo", motor, TS, switching="sign").switching == "sign"


def test_misspelt_name_and_foreign_option_are_refused():
    motor = presets.book_motor()
    with pytest.raises(ParameterError, match=r"unknown observer 'smo_pll' \(did you mean 'smo-pll'\?\)"):
        build(OBSERVERS, "smo_pll", motor, TS)
    with pytest.raises(ParameterError, match="option\\(s\\) hf_voltage do not apply to observer 'ekf'"):
        build(OBSERVERS, "ekf", motor, TS, hf_voltage=20.0)
