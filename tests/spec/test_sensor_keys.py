"""The drive file's ``[sensor]`` current-sensor and encoder-offset keys and their ``[tolerances]``: read,
reported in the spec's summary, built by the assembler, and refused in one line naming the key and the fix
in the user's units."""

import pytest

from pmsmjax.io.drive_files import drive_spec
from pmsmjax.spec.validation import ParameterError

MOTOR = """[motor]
R = 0.958
L_d = 0.00525
L_q = 0.00525
psi_f = 0.1827
pole_pairs = 4
J = 0.003
B = 0.008
[ratings]
rated_speed_rpm = 1000.0
rated_torque_nm = 10.0
max_current_a = 15.0
"""


def _spec(tmp_path, sensor: str, tolerances: str = ""):
    path = tmp_path / "drive.toml"
    path.write_text(MOTOR + "[sensor]\n" + sensor + ("\n[tolerances]\n" + tolerances if tolerances else ""))
    return drive_spec(path)


def test_the_sensor_keys_are_read_reported_and_built(tmp_path):
    spec = _spec(
        tmp_path,
        'kind = "encoder"\nlines = 2500\nencoder_offset_rad = 0.09\ncurrent_offset_a = [0.11, -0.07]\n'
        "current_gain = [1.0, 1.018]\ncurrent_lsb_a = 0.01",
        "current_offset_a = 0.05\ncurrent_gain = 0.01",
    )
    summary = spec.summary()
    assert summary["sensor"]["current_offset_a"] == (0.11, -0.07)
    assert summary["sensor"]["encoder_offset_rad"] == 0.09
    assert summary["tolerances"] == {"current_offset_a": 0.05, "current_gain": 0.01}
    from pmsmjax.assemble import spec_drive

    drive = spec_drive(spec)
    assert drive.current_sensor.offset_a.tolist() == pytest.approx([0.11, -0.07])
    assert drive.current_sensor.gain.tolist() == pytest.approx([1.0, 1.018])
    assert float(drive.current_sensor.lsb_a) == pytest.approx(0.01)
    assert float(drive.estimator.offset_rad) == pytest.approx(0.09)
    # An LSB alone: three exact sensors, quantised.
    spec = _spec(tmp_path, "current_lsb_a = 0.01")
    assert spec.sensor["current_offset_a"] == (0.0, 0.0, 0.0) and spec.sensor["current_gain"] == (1.0,) * 3


@pytest.mark.parametrize(
    "sensor, tolerances, message",
    [
        ("current_offset_a = [5.0, 0.0]", "", r"current_offset_a\[0\] = 5 A is 33.3 % of the 15 A maximum"),
        ("current_offset_a = [0.0, 0.0]\ncurrent_gain = [1.0, 18]", "", r"current_gain\[1\] = 18 is not a "
         r"sensor gain .* 1.18 for 18 % or 1.018 for 1.8 %"),
        ("current_offset_a = [0.1, 0.0]\ncurrent_gain = [1.0, 1.0, 1.0]", "", "current_offset_a has 2 values "
         "and current_gain 3"),
        ("current_offset_a = [0.1]", "", "has 1 values: give 2"),
        ('current_offset_a = ["0.1", 0.0]', "", "holds strings"),
        ('kind = "encoder"\nlines = 2500\nencoder_offset_rad = 12.0', "",
         "beyond 2 pi: it looks like degrees: write 0.20944"),
        ("encoder_offset_rad = 0.09", "", 'apply to kind = "encoder" only'),
        ("current_lsb_a = 2.0", "", "coarser than a 5-bit converter"),
        ("current_offset_a = [0.1, 0.0]", "current_offset_a = 50.0",
         r"\[tolerances\] current_offset_a = 50 A"),
        ("", "current_gain = 0.01", r"spread the current sensors, which \[sensor\] does not give"),
    ],
)  # fmt: skip
def test_sensor_refusals_name_the_key_and_the_fix(tmp_path, sensor, tolerances, message):
    with pytest.raises(ParameterError, match=message) as refused:
        _spec(tmp_path, sensor, tolerances)
    assert "\n" not in str(refused.value)


def test_a_multiphase_drive_refuses_current_sensor_errors(tmp_path):
    from pmsmjax.assemble import current_sensor_parts

    spec = _spec(tmp_path, "current_offset_a = [0.1, 0.0]")
    with pytest.raises(ParameterError, match="modelled for three-phase drives; this is a six-phase drive"):
        current_sensor_parts(spec, "six-phase")


def test_the_demo_summary_names_the_sensors(tmp_path):
    from pmsmjax.assemble import spec_drive
    from pmsmjax.jobs.demo import sensors_entry

    spec = _spec(
        tmp_path,
        'kind = "encoder"\nlines = 2500\nencoder_offset_rad = 0.09\ncurrent_offset_a = [0.11, -0.07]\n'
        "current_gain = [1.0, 1.018]",
    )
    assert sensors_entry(spec_drive(spec)) == {
        "current": {
            "sensed_phases": "ab",
            "reconstructed": "c = -a - b",
            "offset_a": [0.11, -0.07],
            "gain": [1.0, 1.018],
            "lsb_a": None,
        },
        "encoder": {"lines": 2500, "delay_s": 0.0, "offset_rad": 0.09},
    }
    assert sensors_entry(spec_drive(_spec(tmp_path, ""))) == {"current": "ideal"}
