"""The speed cascade every cascaded controller shares (pmsmjax/controllers/speed_cascade.py): FOC, the
multi-phase FOC, hysteresis current control and the two DTCs are speed cascades, and each refuses a
non-positive current limit, an unknown mode and a speed divider that is not a whole number of periods in one
line naming the field."""

import dataclasses

import jax
import numpy as np
import pytest

from pmsmjax import presets
from pmsmjax.controllers.design import speed_loop_active_damping
from pmsmjax.controllers.speed_cascade import AbstractDesignedSpeedCascade, AbstractSpeedCascade
from pmsmjax.presets.six_phase import six_phase_drive
from pmsmjax.spec.validation import ParameterError

CONTROLLERS = {
    "foc": lambda: presets.book_drive().controller,
    "multiphase_foc": lambda: six_phase_drive().controller,
    "hysteresis": lambda: presets.hysteresis_drive().controller,
    "dtc": lambda: presets.dtc_drive().controller,
    "smc_dtc": lambda: presets.smc_dtc_drive().controller,
}


@pytest.mark.parametrize("name", CONTROLLERS)
def test_every_cascaded_controller_is_a_speed_cascade(name):
    controller = CONTROLLERS[name]()
    assert isinstance(controller, AbstractSpeedCascade)
    assert controller.mode == controller.modes[0] == "speed"
    assert isinstance(controller.speed_divider, int) and controller.speed_divider >= 1


@pytest.mark.parametrize("name", CONTROLLERS)
@pytest.mark.parametrize(
    "field, value, needle",
    [
        ("speed_divider", 0, "speed_divider must be an int >= 1, got 0"),
        ("speed_divider", 2.5, "speed_divider must be an int >= 1, got 2.5"),
        ("mode", "position", "mode must be 'speed' or"),
        ("current_limit", -1.0, "current_limit must be > 0"),
    ],
)
def test_each_refuses_a_bad_cascade_field_naming_it(name, field, value, needle):
    controller = CONTROLLERS[name]()
    with pytest.raises(ParameterError, match=needle.replace("(", r"\(")):
        dataclasses.replace(controller, **{field: value})


def test_the_divider_is_counted_in_the_controllers_own_periods():
    """A FOC counts control periods; a comparator controller counts its samples (the message says which)."""
    foc, hysteresis = CONTROLLERS["foc"](), CONTROLLERS["hysteresis"]()
    assert foc.divider_unit == "control periods"
    assert hysteresis.divider_unit != foc.divider_unit
    with pytest.raises(ParameterError, match=hysteresis.divider_unit):
        dataclasses.replace(hysteresis, speed_divider=0)


@pytest.mark.parametrize("name", ["hysteresis", "dtc", "smc_dtc"])
def test_a_designed_cascade_designs_its_speed_loop_from_the_bandwidth(name):
    """Without a speed block given, the comparator controllers design the PI with active damping at
    ``speed_bandwidth`` from their motor model (the design rule's own gains, leaf for leaf)."""
    make = {
        "hysteresis": presets.hysteresis_drive,
        "dtc": presets.dtc_drive,
        "smc_dtc": presets.smc_dtc_drive,
    }
    controller = make[name](speed_bandwidth=40.0).controller
    assert isinstance(controller, AbstractDesignedSpeedCascade)
    expected = speed_loop_active_damping(presets.book_motor(), 40.0)
    for got, want in zip(jax.tree.leaves(controller.speed), jax.tree.leaves(expected), strict=True):
        np.testing.assert_array_equal(np.asarray(got), np.asarray(want))
