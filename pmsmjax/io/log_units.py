"""The units of a log's canonical columns: the accepted units and their factors to SI, units read from
column names (``Time [ms]``, ``i_a (A)``, ``Ia/mA``), and the conversion to SI.

A unit is stated per column or per group (``current``, ``voltage``) in a units map (``--units``, a
config's ``[units]``), or by the column's name: a suffix in brackets or parentheses, or after the last
``/``, that is a unit of the table below (``Phase A [A]``; a bracketed word that is no unit, ``CH1 [probe]``,
is part of the name). A name's unit and a stated one that disagree are refused, as is a unit of the wrong
kind (``i_a [V]``).

``erpm`` is the electrical speed in r/min, as VESC firmware logs it: ``omega_m = erpm * 2 pi / 60 /
pole_pairs`` (mechanical rad/s), so it needs the pole pairs.
"""

import math
import re

import numpy as np

from pmsmjax.spec.validation import ParameterError

__all__ = ["UNITS", "ALIASES", "unit_group", "split_unit", "merge_units", "apply_units"]

#: Accepted units: canonical column (or group) -> {unit: factor to SI}. ``erpm``'s factor is per pole pair.
UNITS = {
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6},
    "omega_m": {"rad/s": 1.0, "rpm": math.pi / 30.0, "Hz": 2.0 * math.pi, "erpm": math.pi / 30.0},
    "theta_e": {"rad": 1.0, "deg": math.pi / 180.0},
    "current": {"A": 1.0, "mA": 1e-3},
    "voltage": {"V": 1.0, "mV": 1e-3, "kV": 1e3},
    "duty": {"1": 1.0, "%": 1e-2},
    "T_L": {"N m": 1.0, "Nm": 1.0},
    "temperature_c": {"degC": 1.0, "C": 1.0},
    "encoder_counts": {"counts": 1.0},
}
#: Other spellings of the units above (in names and maps).
ALIASES = {
    "µs": "us", "μs": "us", "sec": "s", "r/min": "rpm", "1/min": "rpm", "rev/s": "Hz", "°": "deg",
    "°C": "degC", "degc": "degC", "N·m": "N m", "-": "1", "counts": "counts", "cnt": "counts",
}  # fmt: skip
_ALL = {u for table in UNITS.values() for u in table} | set(ALIASES)
_BRACKETS = re.compile(r"^(.*?)\s*[\[(]\s*([^\[\]()]+?)\s*[\])]\s*$")


def unit_group(column: str) -> str | None:
    """The units table of a canonical column (``i_a`` -> ``current``), or None for one without units."""
    if column in UNITS:
        return column
    if column.startswith("i_"):
        return "current"
    if column.startswith("u_") or column == "U_dc":
        return "voltage"
    if column.startswith("d_"):
        return "duty"
    return None


def _normal(unit: str) -> str:
    return ALIASES.get(unit, ALIASES.get(unit.lower(), unit))


def split_unit(name: str) -> tuple[str, str | None]:
    """``(name without its unit, unit or None)``: ``"Time [ms]"`` -> ``("Time", "ms")``, ``"Ia/mA"`` ->
    ``("Ia", "mA")``, ``"omega/rad/s"`` -> ``("omega", "rad/s")``; a suffix that is no known unit stays in
    the name."""
    m = _BRACKETS.match(name)
    if m and m.group(1) and m.group(2) in _ALL:
        return m.group(1).strip(), _normal(m.group(2))
    for unit in sorted(_ALL, key=len, reverse=True):
        if name.endswith("/" + unit) and len(name) > len(unit) + 1:
            return name[: -len(unit) - 1].strip(), _normal(unit)
    return name, None


def merge_units(named: dict, stated: dict, source: str) -> dict:
    """The units map with the units the column names give (`named`, ``{canonical: unit}``) added to the
    `stated` ones (``--units``, ``[units]``); a stated unit that contradicts a name's is refused."""
    out = dict(stated)
    for column, unit in named.items():
        group = unit_group(column)
        given = stated.get(column, stated.get(group) if group in ("current", "voltage") else None)
        if given is not None and _normal(str(given)) != unit:
            key = column if column in stated else group
            raise ParameterError(
                f"{source}: units {key} = {given!r} contradicts the name of the column read as {column}, "
                f"which says {unit}: drop the unit from --units or [units], or correct it."
            )
        out[column] = unit
    return out


def apply_units(c: dict, units: dict, source: str, pole_pairs: int | None = None) -> None:
    """Convert the columns of ``c`` in place to SI by ``units`` (``{column or group: unit}``; a column's
    own unit wins over its group's). ``erpm`` needs `pole_pairs`."""
    for key, unit in units.items():
        group = unit_group(key) if key not in ("current", "voltage") else key
        if group is None:
            raise ParameterError(
                f"units: unknown key {key!r}; use time, omega_m, theta_e, T_L, temperature_c, current, "
                "voltage or a column."
            )
        if _normal(str(unit)) not in UNITS[group]:
            raise ParameterError(f"units: {key} = {unit!r} is not one of {', '.join(UNITS[group])}.")
    for name in list(c):
        group = unit_group(name)
        unit = units.get(name, units.get(group) if group in ("current", "voltage") else None)
        if unit is None:
            continue
        unit = _normal(str(unit))
        factor = UNITS[group][unit]
        if unit == "erpm":
            if pole_pairs is None:
                raise ParameterError(
                    f"{source}: {name} in erpm (electrical r/min) needs the pole pairs to become a "
                    "mechanical speed: give --pole-pairs or --motor."
                )
            factor = factor / pole_pairs
        c[name] = np.asarray(c[name], dtype=np.float64) * factor
