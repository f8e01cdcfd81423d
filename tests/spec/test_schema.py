"""The drive file's schema (pmsmjax/spec/schema.py) on raw tables: a seven-value motor file is a drive file
with only [motor]; wrong types, signs and missing encoder lines are refused in one line naming the table,
the key and the unit."""

import pytest

from pmsmjax.spec import schema
from pmsmjax.spec.validation import ParameterError

WHERE = "drive file x.toml"
MOTOR = dict(R=0.958, L_d=5.25e-3, L_q=5.25e-3, psi_f=0.1827, pole_pairs=4, J=0.003, B=0.008)


def test_a_motor_file_is_a_drive_file_with_only_its_motor():
    tables = schema.split_tables(dict(MOTOR), WHERE)
    assert tables["motor"] == MOTOR
    assert set(tables) == set(schema.TABLES) and not any(tables[t] for t in tables if t != "motor")
    assert schema.read_motor(tables["motor"], WHERE, 3) == MOTOR


def test_refusals_name_table_key_and_unit():
    with pytest.raises(ParameterError, match=r"\[inverter\] u_dc_v = -311 V: give a finite number above 0"):
        schema.numbers({"u_dc_v": -311.0}, "inverter", WHERE)
    with pytest.raises(ParameterError, match=r"\[motor\] pole_pairs must be a whole number"):
        schema.read_motor({**MOTOR, "pole_pairs": 4.5}, WHERE, 3)
    with pytest.raises(ParameterError, match=r"\[sensor\] lines must be the encoder's lines per revolution"):
        schema.read_sensor({"kind": "encoder"}, WHERE)
    with pytest.raises(ParameterError, match=r"unknown keys \['Rs'\] in \[motor\] \('Rs' looks like 'R'\)"):
        schema.check_keys("motor", {**MOTOR, "Rs": 1.0}, WHERE)


def test_a_drive_file_that_is_not_toml_is_refused_in_one_line(tmp_path):
    """The drive-file reader parses with [`pmsmjax.io.toml_parser`]'s ``tomllib`` and turns its error
    into one line naming the file."""
    from pmsmjax.io.drive_files import read_drive_file
    from pmsmjax.io.toml_parser import tomllib

    path = tmp_path / "motor.toml"
    path.write_text("[motor]\nR = 0.958\nL_d = \n")
    with pytest.raises(tomllib.TOMLDecodeError):
        tomllib.loads(path.read_text())
    with pytest.raises(ParameterError, match=r"drive file .*motor\.toml: not valid TOML") as err:
        read_drive_file(path)
    assert "\n" not in str(err.value)
