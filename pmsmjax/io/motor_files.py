"""Motors by name or file as plain numbers, read and checked without JAX: the ``[motor]`` table of a drive
file ([`pmsmjax.io.drive_files`][pmsmjax.io.drive_files], the one reader).

[`motor_values`][pmsmjax.io.motor_files.motor_values] gives
``{"R", "L_d", "L_q", "psi_f", "pole_pairs", "J", "B"}`` (SI: ohm, H, H, Wb, -, kg m^2, N m s/rad) for a
preset name or a drive file; [`pmsmjax.presets.load_motor`][pmsmjax.presets.three_phase.load_motor] builds the
[`PMSMParameters`][pmsmjax.machines.motor.PMSMParameters] from it. A seven-value motor file (the values at top
level or under ``[motor]``, optionally ``trust_units = true`` to skip the unit plausibility check of
[`pmsmjax.spec.plausibility`][pmsmjax.spec.plausibility]) is a drive file with only its motor; a file with
``[ratings]``, ``[inverter]``, ... tables reads the same way, its inverter's control period setting the
time-constant check.
"""

from pmsmjax.io.drive_files import drive_spec, read_drive_file
from pmsmjax.spec.drive_spec import MOTOR_FIELDS

__all__ = ["MOTOR_FIELDS", "motor_values", "read_motor_file"]


def _motor(spec) -> dict:
    return {f: spec.motor[f] for f in MOTOR_FIELDS}


def motor_values(name_or_path, *, check_units: bool = True) -> dict:
    """The three-phase motor of a preset name or a drive file (read and checked,
    [`pmsmjax.io.drive_files.drive_spec`][pmsmjax.io.drive_files.drive_spec])."""
    return _motor(drive_spec(name_or_path, check_units=check_units))


def read_motor_file(path, *, check_units: bool = True) -> dict:
    """``{field: value}`` of a three-phase motor or drive file; every problem is a one-line
    [`ParameterError`][pmsmjax.spec.validation.ParameterError] naming the file, the key and the fix."""
    return _motor(read_drive_file(path, n_phases=3, check_units=check_units))
