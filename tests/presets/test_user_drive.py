"""The drive file put into the presets: the book drive file gives the book presets bit for bit, and the
three drives shipped as examples (not the book's) reach their rated speed under 0.8 x rated torque
inside their current limit with the derived design rules."""

import equinox as eqx
import numpy as np
import pytest

from pmsmjax import presets, simulate
from pmsmjax.analysis.operating_point import run_flags
from pmsmjax.analysis.speed_step_summary import speed_step_summary
from pmsmjax.assemble import spec_drive, spec_scenario, startup_options
from pmsmjax.io.drive_files import drive_spec, preset_path
from pmsmjax.presets.control_methods import CONTROLS, control_drive
from pmsmjax.presets.five_phase import five_phase_drive
from pmsmjax.presets.six_phase import six_phase_drive

EXAMPLE_DRIVES = ("servo-400w", "industrial-5k6w", "outer-rotor-24v")


@pytest.mark.parametrize("control", list(CONTROLS))
def test_book_file_is_the_book_drive(control):
    assert eqx.tree_equal(spec_drive(drive_spec("book"), control), control_drive(control))


def test_book_file_scenario_and_startup_are_the_books():
    spec = drive_spec("book")
    assert eqx.tree_equal(spec_scenario(spec), presets.book_scenario())
    assert startup_options(spec) == presets.STARTUP_DEFAULTS
    assert spec.derived.keys() == {
        "inverter.control_frequency_hz",
        "inverter.device_drop_v",
        "inverter.dead_time_compensation",
        "ratings.rated_current_a",
    }


@pytest.mark.parametrize("n_phases, build", [(6, six_phase_drive), (5, five_phase_drive)])
def test_multiphase_book_files_are_the_book_rewinds(n_phases, build):
    assert eqx.tree_equal(spec_drive(drive_spec("book", n_phases=n_phases)), build())


@pytest.mark.parametrize("name", EXAMPLE_DRIVES)
def test_example_drive_reaches_rated_speed_under_load(name):
    spec = drive_spec(name)
    assert spec.scenario["speed_rpm"] == spec.ratings["rated_speed_rpm"]
    assert spec.scenario["load_nm"] == pytest.approx(0.8 * spec.ratings["rated_torque_nm"])
    drive = spec_drive(spec)
    trace = simulate(drive, spec_scenario(spec)).to_numpy()
    load_time = spec.scenario["load_time_s"]
    summary = speed_step_summary(trace, load_time_s=load_time, current_limit_a=spec.current_limit_a)
    assert (
        abs(summary["final_speed_rpm"] - spec.ratings["rated_speed_rpm"])
        < 0.005 * spec.ratings["rated_speed_rpm"]
    )
    i_peak = np.max(np.abs(np.asarray(trace.i_abc)))
    assert i_peak <= 1.01 * spec.current_limit_a
    assert run_flags(trace, drive, load_time_s=load_time)["flags"] == []


def test_file_dead_time_reaches_the_bridge_and_the_compensation(tmp_path):
    """The servo's 0.5 us at 20 kHz: in the averaged bridge and, by default, compensated in the FOC with
    the same estimates; ``dead_time_compensation = false`` leaves the controller bare. With the control at
    twice the switching rate the engine's period is half the PWM period, so the dead time is halved: the
    lost share of the voltage, t_d / T_pwm = 1 %, is kept."""
    drive = spec_drive(drive_spec("servo-400w"))
    error = drive.bridge.voltage_error
    assert float(error.dead_time) == 5e-7 and float(error.device_drop) == 0.0
    assert float(error.current_scale) == pytest.approx(0.02 * 36.0, rel=1e-12)  # 2 % of max_current_a
    assert eqx.tree_equal(drive.controller.dead_time_compensation.estimate, error)
    assert spec_drive(drive_spec("servo-400w"), "hysteresis").bridge.voltage_error is not None

    extra = "device_drop_v = 1.2\ndead_time_compensation = false\ncontrol_frequency_hz = 40000.0"
    path = tmp_path / "servo.toml"
    path.write_text(
        preset_path("servo-400w").read_text().replace("dead_time_s = 5e-7", f"dead_time_s = 5e-7\n{extra}")
    )
    spec = drive_spec(path)
    drive = spec_drive(spec)
    assert drive.Ts == 2.5e-5 and drive.controller.dead_time_compensation is None
    error = drive.bridge.voltage_error
    assert float(error.device_drop) == 1.2
    assert float(error.dead_time) / drive.Ts == pytest.approx(5e-7 * 20000.0, rel=1e-12)
