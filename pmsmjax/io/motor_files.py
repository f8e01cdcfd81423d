"""Motors by name or TOML file as plain numbers, read and checked without JAX.

:func:`motor_values` gives ``{"R", "L_d", "L_q", "psi_f", "pole_pairs", "J", "B"}`` (SI: ohm, H, H, Wb,
-, kg m^2, N m s/rad) for a preset name or a motor file; :func:`pmsmjax.presets.load_motor` builds the
:class:`~pmsmjax.machines.motor.PMSMParameters` from it. The command line uses it to check a motor (its
units, whether an operating point is reachable) before JAX starts.

A motor file holds the seven values at top level or under ``[motor]``, and optionally
``trust_units = true`` to skip the unit plausibility check (:mod:`pmsmjax.checks.plausibility`) for a genuine
motor outside its ranges.
"""

import sys
from pathlib import Path

from pmsmjax.checks.plausibility import check_motor_units
from pmsmjax.checks.validation import ParameterError
from pmsmjax.presets.book_constants import BOOK_MOTOR, BOOK_SALIENT_MOTOR

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["MOTOR_FIELDS", "PRESET_VALUES", "motor_values", "read_motor_file"]

MOTOR_FIELDS = ("R", "L_d", "L_q", "psi_f", "pole_pairs", "J", "B")

#: The motors by preset name: the book's surface motor and its salient variant (L_q = 12 mH) for HF
#: injection (:mod:`pmsmjax.presets.book_constants`); read-only.
PRESET_VALUES = {"book": BOOK_MOTOR, "book_salient": BOOK_SALIENT_MOTOR}


def motor_values(name_or_path, *, check_units: bool = True, Ts: float | None = None) -> dict | None:
    """The values of a preset (copied) or of a motor file (read and checked); ``None`` for a preset name
    this module does not know (one only :mod:`pmsmjax.presets` builds). `Ts`: control period, s, for
    the time-constant check."""
    key = str(name_or_path)
    if key in PRESET_VALUES:
        return dict(PRESET_VALUES[key])
    if Path(key).is_file():
        return read_motor_file(key, check_units=check_units, Ts=Ts)
    return None


def read_motor_file(path, *, check_units: bool = True, Ts: float | None = None) -> dict:
    """``{field: value}`` from a motor TOML file; every problem is a :class:`ParameterError` naming the
    file, the key and the fix."""
    path = Path(path)
    if not path.is_file():
        raise ParameterError(f"motor file {path} does not exist: check the path.")
    try:
        data = tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as err:
        raise ParameterError(f"motor file {path}: not valid TOML ({err}).") from err
    data = data.get("motor", data)
    trust = data.get("trust_units", False)
    if not isinstance(trust, bool):
        raise ParameterError(f"motor file {path}: trust_units must be true or false, got {trust!r}.")
    missing = [f for f in MOTOR_FIELDS if f not in data]
    if missing:
        raise ParameterError(
            f"motor file {path} lacks {', '.join(missing)}: it needs R, L_d, L_q, psi_f, pole_pairs, J, B "
            "(SI units: ohm, H, H, Wb, -, kg m^2, N m s)."
        )
    unknown = sorted(set(data) - set(MOTOR_FIELDS) - {"trust_units"})
    if unknown:
        import difflib

        hints = [
            f"{u!r} looks like {m[0]!r}"
            for u in unknown
            if (m := difflib.get_close_matches(u, MOTOR_FIELDS + ("trust_units",), 1, 0.6))
        ]
        raise ParameterError(
            f"motor file {path}: unknown keys {unknown}; allowed: {', '.join(MOTOR_FIELDS)}, trust_units"
            + (f" ({'; '.join(hints)})" if hints else "")
            + "."
        )
    values = {}
    for f in MOTOR_FIELDS:
        v = data[f]
        if f == "pole_pairs":
            if not isinstance(v, int) or isinstance(v, bool):
                raise ParameterError(f"motor file {path}: pole_pairs must be an integer, got {v!r}.")
            values[f] = v
        else:
            if not isinstance(v, (int, float)) or isinstance(v, bool):
                raise ParameterError(f"motor file {path}: {f} must be a number, got {v!r}.")
            values[f] = float(v)
    if check_units and not trust and all(values[f] > 0 for f in ("R", "L_d", "L_q")):
        check_motor_units(values, f"motor file {path}", Ts)
    return values
