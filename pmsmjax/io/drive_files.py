"""Drive files: read a drive file (TOML) or a preset by name into a checked
[`DriveSpec`][pmsmjax.spec.drive_spec.DriveSpec], and write one.

Reading is the file's part only: the TOML, its tables and the ``[motor] flux_map`` file beside it
([`pmsmjax.io.flux_map_files`][pmsmjax.io.flux_map_files], in the layout ``[motor] flux_map_format`` names,
[`pmsmjax.io.flux_map_formats`][pmsmjax.io.flux_map_formats]); the checks, defaults and derivations are the
spec's ([`pmsmjax.spec.drive_spec`][pmsmjax.spec.drive_spec], whose docstring has the layout). The presets are
drive files in ``pmsmjax/presets/motors/``.
"""

from collections.abc import Mapping
from pathlib import Path

from pmsmjax.io.flux_map_files import read_flux_map_file
from pmsmjax.io.toml_parser import read_toml, tomllib
from pmsmjax.spec.datasheet import refuse_ambiguous
from pmsmjax.spec.drive_spec import (
    MOTOR_FIELDS,
    TABLES,
    DriveSpec,
    check_keys,
    complete,
    flux_map_name,
    split_tables,
)
from pmsmjax.spec.validation import ParameterError

__all__ = [
    "DriveSpec",
    "drive_spec",
    "read_drive_file",
    "write_drive_file",
    "preset_path",
    "PRESET_FILES",
    "TABLES",
    "MOTOR_FIELDS",
]

#: Preset names and their drive files in ``pmsmjax/presets/motors/`` (three-phase; the six- and
#: five-phase rewinds of the book motor by ``n_phases``).
PRESET_FOLDER = Path(__file__).resolve().parents[1] / "presets" / "motors"
PRESET_FILES = {
    "book": "book.toml",
    "book_salient": "book_salient.toml",
    "saturated-ipm": "saturated_ipm.toml",
    "pm-syrm": "pm_syrm.toml",
    "servo-400w": "servo_400w_48v.toml",
    "servo-two-mass": "servo_two_mass.toml",
    "industrial-5k6w": "industrial_5k6w_540v.toml",
    "outer-rotor-24v": "outer_rotor_24v.toml",
}
MULTIPHASE_PRESET_FILES = {
    (6, "book"): "six_phase_book.toml",
    (6, "book_salient"): "six_phase_book_salient.toml",
    (5, "book"): "five_phase_book.toml",
    (5, "book_salient"): "five_phase_book_salient.toml",
}


def preset_path(name: str, n_phases: int = 3) -> Path | None:
    """The drive file of preset ``name`` for an ``n_phases`` machine, or None."""
    file = PRESET_FILES.get(name) if n_phases == 3 else MULTIPHASE_PRESET_FILES.get((n_phases, name))
    return None if file is None else PRESET_FOLDER / file


def drive_spec(
    name_or_path,
    *,
    n_phases: int = 3,
    u_dc_v: float | None = None,
    max_current_a: float | None = None,
    check_units: bool = True,
    flags: Mapping[str, str] | None = None,
) -> DriveSpec:
    """The drive of a preset name or a drive file, ``u_dc_v`` (V) and ``max_current_a`` (A) overriding
    the file's (``--u-dc``, ``--current-limit``), checked and completed. `flags`: how messages name the
    overrides (``{"u_dc_v": "--u-dc"}``). A preset name unknown for ``n_phases`` phases is refused."""
    key = str(name_or_path)
    path = preset_path(key, n_phases)
    if path is None:
        path = Path(key)
        if not path.is_file():
            names = (
                [n for (k, n) in MULTIPHASE_PRESET_FILES if k == n_phases] if n_phases != 3 else PRESET_FILES
            )
            kind = "is a folder" if path.is_dir() else "does not exist"
            raise ParameterError(
                f"--motor {key}: neither a preset ({', '.join(names)}) nor a drive file (the path {kind}): "
                "give a preset name or the path of a drive TOML file."
            )
        source = key
    else:
        source = key
    overrides = {k: v for k, v in (("u_dc_v", u_dc_v), ("max_current_a", max_current_a)) if v is not None}
    return read_drive_file(
        path, source=source, n_phases=n_phases, check_units=check_units, overrides=overrides, flags=flags
    )


def read_drive_file(
    path,
    *,
    source: str | None = None,
    n_phases: int | None = None,
    check_units: bool = True,
    overrides: Mapping[str, float] | None = None,
    flags: Mapping[str, str] | None = None,
) -> DriveSpec:
    """Read the drive file ``path`` and check and complete it
    ([`pmsmjax.spec.drive_spec.complete`][pmsmjax.spec.drive_spec.complete]). `n_phases`: the machine the
    command runs (a file for another is refused); `overrides`: ``u_dc_v``/``max_current_a`` from flags."""
    path = Path(path)
    where = f"drive file {path}"
    if not path.is_file():
        raise ParameterError(f"{where} does not exist: check the path.")
    data = read_toml(path, where)
    tables = split_tables(data, where)
    refuse_ambiguous(tables["motor"], where)
    for table, values in tables.items():
        check_keys(table, values, where)
    grid = map_path = None
    how = ""
    fmt = tables["motor"].pop("flux_map_format", None)
    if fmt is not None and "flux_map" not in tables["motor"]:
        raise ParameterError(
            f'{where}: [motor] flux_map_format = {fmt!r} without a flux_map: add flux_map = "map.csv" or '
            "drop the format."
        )
    if fmt is not None and not isinstance(fmt, str):
        raise ParameterError(f'{where}: [motor] flux_map_format must be a name (e.g. "syre"), got {fmt!r}.')
    if "flux_map" in tables["motor"]:
        name = flux_map_name(tables["motor"], where)
        map_path = Path(name) if Path(name).is_absolute() else path.resolve().parent / name
        if not map_path.is_file():
            state = "is a folder, not a map file" if map_path.is_dir() else "does not exist"
            raise ParameterError(
                f"{where}: [motor] flux_map = {name!r}: {map_path} {state} (the path is relative to "
                "the drive file's folder)."
            )
        read = read_flux_map_file(map_path, fmt, name=f"{where}: [motor] flux_map_format")
        grid, how = read.grid, read.how
    return complete(
        tables, where=where, source=str(source if source is not None else path), n_phases=n_phases,
        check_units=check_units, overrides=overrides, flags=flags, flux_map=grid,
        flux_map_path=None if map_path is None else str(map_path), flux_map_how=how,
    )  # fmt: skip


def _one_line(text) -> str:
    return " ".join(str(text).split())


def write_drive_file(path, tables: Mapping[str, Mapping], header: str = "", comments: Mapping | None = None):
    """Write ``tables`` (``{"motor": {...}, "tolerances": {...}, ...}``, the layout of the module
    docstring) as a drive file, atomically; `comments`: ``{"table.key": text}`` written after a value.
    Numbers keep their full precision (``repr``)."""
    from pmsmjax.io.logs import atomic_write

    comments = comments or {}
    lines = [f"# {line}" for line in header.splitlines()] + ([""] if header else [])
    for table in TABLES:
        values = tables.get(table)
        if not values:
            continue
        lines.append(f"[{table}]")
        for key, value in values.items():
            if isinstance(value, bool):
                text = "true" if value else "false"
            elif isinstance(value, str):
                text = f'"{value}"'
            elif isinstance(value, (list, tuple)) and value and isinstance(value[0], (list, tuple)):
                number = lambda v: (
                    str(v) if isinstance(v, int) and not isinstance(v, bool) else repr(float(v))
                )
                text = "[" + ", ".join("[" + ", ".join(map(number, row)) + "]" for row in value) + "]"
            elif isinstance(value, (list, tuple)):
                text = "[" + ", ".join(repr(float(v)) for v in value) + "]"
            elif isinstance(value, int):
                text = str(value)
            else:
                text = repr(float(value))
            note = comments.get(f"{table}.{key}")
            lines.append(f"{key} = {text}" + (f"  # {note}" if note else ""))
        lines.append("")
    text = "\n".join(lines)
    tomllib.loads(text)  # what is written must read back
    return atomic_write(path, lambda f: f.write(text), mode="w")
