"""A two-mass drive file: ``[mechanics]``, the ``[control]`` speed-loop filters and the shaft tolerances.

The servo-two-mass preset is read, completed and built (the plant's motor carries the shaft, the
controller's model and design rule the total inertia, the speed PI its filters); without the tables the
drive is the rigid one; careless values are refused in one line naming the key and the fix.
"""

import numpy as np
import pytest

from pmsmjax.assemble import spec_drive
from pmsmjax.io.drive_files import PRESET_FOLDER, drive_spec
from pmsmjax.spec.validation import ParameterError

SERVO = (PRESET_FOLDER / "servo_two_mass.toml").read_text()
FILTERS = "[control]\nspeed_filter_hz = 800.0\nnotch_hz = 200.0\n"


def servo_file(tmp_path, old="", new=""):
    path = tmp_path / "servo.toml"
    path.write_text(SERVO.replace(old, new) if old else SERVO)
    return path


def refusal(path) -> str:
    with pytest.raises(ParameterError) as info:
        drive_spec(path)
    message = str(info.value)
    assert "\n" not in message
    return message


def test_preset_reads_and_builds_a_two_mass_drive(tmp_path):
    spec = drive_spec(servo_file(tmp_path, "[control]\n", FILTERS))
    assert dict(spec.mechanics) == {
        "load_inertia": 1e-4, "shaft_stiffness_nm_per_rad": 52.6, "shaft_damping_nm_s_per_rad": 0.0017,
    }  # fmt: skip
    assert spec.control["notch_width_hz"] == 100.0 and spec.control["notch_depth_db"] == 20.0
    assert "control.notch_width_hz" in spec.derived
    assert spec.summary()["mechanics"]["load_inertia"] == 1e-4
    drive = spec_drive(spec, "pi")
    m = drive.machine.motor
    np.testing.assert_allclose(
        [float(m.J), float(m.load_inertia), float(m.shaft_stiffness)], [5e-5, 1e-4, 52.6]
    )
    np.testing.assert_allclose(float(drive.controller.model.J), 1.5e-4)  # designed for the total inertia
    f = drive.controller.speed.filters
    np.testing.assert_allclose([float(f.speed_filter_hz), float(f.notch_hz)], [800.0, 200.0])


def test_without_the_tables_the_drive_is_rigid(tmp_path):
    text = SERVO.split("\n[mechanics]\n")[0] + "\n[ratings]\n" + SERVO.split("\n[ratings]\n")[1]
    text = text.split("[tolerances]")[0]
    path = tmp_path / "rigid.toml"
    path.write_text(text)
    drive = spec_drive(drive_spec(path), "pi")
    assert drive.machine.motor.load_inertia is None and drive.controller.speed.filters is None


@pytest.mark.parametrize(
    "old, new, match",
    [
        ("shaft_stiffness_nm_per_rad = 52.6", "shaft_stiffness_nm_per_rad = 0.0009",
         "shaft_stiffness_nm_per_rad = 0.0009 gives a shaft resonance of"),
        ("load_inertia = 0.0001 ", "load_inertia = 1000.0 ", "load_inertia = 1000 kg m^2 is"),
        ("shaft_stiffness_nm_per_rad = 52.6", "", "lacks shaft_stiffness_nm_per_rad"),
        ("shaft_damping_nm_s_per_rad = 0.0017", "shaft_damping_nm_s_per_rad = -1.0",
         "shaft_damping_nm_s_per_rad = -1.0: give a finite number >= 0"),
        ("[control]\n", "[control]\nnotch_hz = 6000.0\n",
         "notch_hz = 6000 Hz is at or above the speed loop's Nyquist frequency 5000 Hz"),
        ("[control]\n", "[control]\nnotch_width_hz = 50.0\n",
         "give notch_hz"),
        ("[control]\n", "[control]\nnotch_hz = 200.0\nnotch_width_hz = 450.0\n",
         "notch_width_hz = 450 Hz is not below twice"),
        ("[control]\n", "[control]\nnotch_hz = 200.0\nnotch_depth_db = 90.0\n",
         "notch_depth_db = 90 dB"),
        ("[control]\n", "[control]\nspeed_filter_hz = 20.0\n",
         "speed_filter_hz = 20 Hz is below the speed loop's bandwidth"),
    ],
)  # fmt: skip
def test_refusals(tmp_path, old, new, match):
    assert match in refusal(servo_file(tmp_path, old, new))


def test_shaft_tolerance_without_a_shaft_is_refused(tmp_path):
    text = SERVO.split("\n[mechanics]\n")[0] + "\n[ratings]\n" + SERVO.split("\n[ratings]\n")[1]
    path = tmp_path / "no_shaft.toml"
    path.write_text(text)
    assert "spread a compliant shaft" in refusal(path)
