"""A drive file's values as blocks (pmsmjax/spec_blocks.py): the book drive file's motor, scenario and I/f
start are the presets' own, a file without a flux map has none, and the scenario's values can be overridden
one by one."""

import jax
import numpy as np

from pmsmjax import presets
from pmsmjax.io.drive_files import drive_spec
from pmsmjax.spec_blocks import spec_flux_map, spec_motor, spec_scenario, startup_options

BOOK = drive_spec("book")


def _equal_leaves(a, b):
    for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))


def test_the_book_files_motor_and_scenario_are_the_presets():
    motor = spec_motor(BOOK)
    assert motor.pole_pairs == presets.book_motor().pole_pairs
    _equal_leaves(motor, presets.book_motor())
    _equal_leaves(spec_scenario(BOOK), presets.book_scenario())


def test_scenario_values_are_overridden_one_by_one():
    s = BOOK.scenario
    changed = spec_scenario(BOOK, speed_rpm=500.0, duration_s=0.2)
    _equal_leaves(changed, presets.book_scenario(500.0, s["load_nm"], s["load_time_s"], 0.2))


def test_no_map_without_one_and_the_map_of_a_map_file():
    assert spec_flux_map(BOOK) is None
    flux_map = spec_flux_map(drive_spec("saturated-ipm"))
    psi, L = flux_map(np.zeros(2))
    assert np.all(np.isfinite(np.asarray(psi))) and np.asarray(L).shape == (2, 2)


def test_the_i_f_start_reads_the_control_table():
    c = BOOK.control
    assert startup_options(BOOK) == {
        "i_start": c["startup_current_a"],
        "accel": c["startup_acceleration_rad_s2"],
        "handover_speed": c["handover_speed_rad_s"],
        "blend_speed": c["blend_speed_rad_s"],
    }
