"""A log read through a column map: the file's names matched to the canonical column names a command
reads, the units their names carry, and the columns converted to SI.

A canonical column ``c`` is the file's column

1. named by the column map (``{canonical: name in file}``, ``--columns c=NAME``, ``[columns]``): the name as
   written, or without its unit suffix (``i_a=Ia`` finds ``Ia/mA``);
2. else the column named ``c``, or ``c`` with a unit suffix (``time [ms]``), or, in any letter case, one
   such column (``Time [ms]``).

The unit a matched name carries ([`pmsmjax.io.log_units.split_unit`][pmsmjax.io.log_units.split_unit])
becomes the column's unit unless a stated one contradicts it.
"""

import os

from pmsmjax.io.csv_dialect import CsvDialect
from pmsmjax.io.log_formats import PresetColumn
from pmsmjax.io.log_units import UNITS, apply_units, merge_units, split_unit, unit_group
from pmsmjax.io.logs import column_names, read_log
from pmsmjax.spec.validation import ParameterError

__all__ = ["resolve_columns", "read_mapped_log"]


def resolve_columns(names, canonical, column_map: dict | None, source: str) -> tuple[dict, dict]:
    """``({canonical: file name}, {canonical: unit from the name})`` for the file column `names` (module
    docstring). A mapped name the file lacks is left out (the caller names it); a name's unit of the wrong
    kind (``i_a [V]``) is refused."""
    column_map = dict(column_map or {})
    names = list(names)
    split = {n: split_unit(n) for n in names}
    found: dict[str, str] = {}
    for c, wanted in column_map.items():
        hits = [n for n in names if n == wanted] or [n for n in names if split[n][0] == wanted]
        if len(hits) == 1:
            found[c] = hits[0]
    taken = set(found.values())
    for c in canonical:
        if c in column_map:
            continue
        free = [n for n in names if n not in taken]
        hits = (
            [n for n in free if n == c]
            or [n for n in free if split[n][0] == c]
            or [n for n in free if split[n][0].lower() == c.lower()]
        )
        if len(hits) == 1:
            found[c] = hits[0]
            taken.add(hits[0])
    units = {}
    for c, n in found.items():
        unit = split[n][1]
        if unit is None or n == c:
            continue
        group = unit_group(c)
        if group is None or unit not in UNITS[group]:
            accepted = ", ".join(UNITS[group]) if group else "none"
            raise ParameterError(
                f"{source}: column {n!r}, read as {c}, says its unit is {unit!r}, which is not a unit of {c} "
                f"(accepted: {accepted}): convert the column, or rename it and state its unit with --units."
            )
        units[c] = unit
    return found, units


def read_mapped_log(
    path: str | os.PathLike,
    required,
    optional=(),
    *,
    columns: dict | None = None,
    units: dict | None = None,
    dialect: CsvDialect | None = None,
    pole_pairs: int | None = None,
    unused: list | None = None,
) -> dict:
    """The canonical `required` and present `optional` columns of the log at ``path`` in SI units, read
    through the column map `columns` and the units map `units` (module docstring), checked as
    [`read_log`][pmsmjax.io.logs.read_log] checks them (a positive unit factor keeps time increasing)."""
    required, optional = tuple(required), tuple(optional)
    source = f"log {path}"
    columns = dict(columns or {})
    unknown = sorted(set(columns) - set(required + optional))
    if unknown:
        raise ParameterError(
            f"column map: {', '.join(unknown)} is not a column this command reads "
            f"({', '.join(required + optional)}): the keys of --columns and [columns] are those names, the "
            "values the names in the file."
        )
    names = column_names(path, dialect)
    found, named = resolve_columns(names, required + optional, columns, source)
    absent = [(c, n) for c, n in columns.items() if c not in found and not isinstance(n, PresetColumn)]
    if absent and names:
        c, n = absent[0]
        raise ParameterError(
            f"column map {c}={n}: log {path} has no column {n!r} (its columns: {', '.join(names)}): map {c} "
            f'to a column the log has (--columns {c}=NAME, or [columns] {c} = "NAME"), or drop the mapping.'
        )
    to_file = {c: found.get(c, c) for c in required + optional}
    file_unused: list[str] = []
    raw = read_log(
        path, [to_file[c] for c in required], [to_file[c] for c in optional], time=to_file.get("time"),
        unused=file_unused,
        dialect=dialect,
    )  # fmt: skip
    back = {n: c for c, n in to_file.items()}
    out = {back[n]: v for n, v in raw.items()}
    if unused is not None:
        unused.extend(file_unused)
    apply_units(out, merge_units(named, dict(units or {}), source), source, pole_pairs)
    return out
