"""Checks of command-line input shared by every subcommand: a bad flag is refused before any work, with
one line naming the flag, the value in the user's unit and the fix, and exit status 2.

Pure Python (no JAX, no Equinox): a refusal comes back in a fraction of a second.

How a subcommand uses it (``pmsmjax/cli/demo.py`` is the worked example):

- one-flag checks as the argparse ``type``::

      p.add_argument("--load-nm", type=checks.real("N m"), default=10.0, help="... (default 10)")
      p.add_argument("--duration-s", type=checks.positive("s"), ...)
      p.add_argument("--dead-time-us", type=checks.nonnegative("us"), ...)
      p.add_argument("--substeps", type=checks.count(), ...)            # an int >= 1

  A bad value ends as ``pmsmjax demo: error: argument --load-nm: nan is not a finite number of N m:
  give one, e.g. 10 (see pmsmjax demo --help)`` (the parser's ``error`` prints that one line).
- first thing in ``run(args)``, before importing anything heavy: `output_folder` for ``--out`` and
  the checks that involve several flags, raising [`ParameterError`][pmsmjax.spec.validation.ParameterError]
  with `flag` to name each flag as the user typed it.
- a [`ParameterError`][pmsmjax.spec.validation.ParameterError] raised later by the library is printed as one
  line by `pmsmjax.cli.main`; `user_terms` turns the library's names (``Drive.n_substeps``) into the
  flags (``--substeps``) where a subcommand maps them.
"""

import argparse
import math
import os
from pathlib import Path

from pmsmjax.spec.validation import ParameterError, plain

__all__ = [
    "Parser",
    "add_out_flag",
    "add_key_values_flag",
    "add_log_column_flags",
    "key_values",
    "log_reading",
    "number",
    "real",
    "positive",
    "nonnegative",
    "count",
    "flag",
    "output_folder",
    "output_file",
    "existing_file",
    "user_terms",
    "plain",
]


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (no usage block) pointing at ``--help``; exit 2."""

    def error(self, message):
        message = " ".join(str(message).split())  # a typed line break or carriage return stays one line
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def add_out_flag(p, default: str | None = None) -> None:
    """``--out``: the command's output folder (created), `default` or, without one, required."""
    if default is None:
        p.add_argument("--out", required=True, help="output folder (created)")
    else:
        p.add_argument("--out", default=default, help=f"output folder (created), default: {default}")


def add_key_values_flag(p, flag: str, metavar: str, help: str) -> None:
    """`flag` taking KEY=VALUE words (``--units time=ms omega_m=rpm``; default none); given again, its words
    add to the earlier ones (``--fix J=1e-3 --fix B=1e-4`` holds both)."""
    p.add_argument(flag, nargs="+", action="extend", default=[], metavar=metavar, help=help)


def add_log_column_flags(
    p, example: str, units_help: str, tables: str = "[columns], [units] and [log]"
) -> None:
    """The flags of every command that reads a log: ``--config`` (a TOML file with `tables`), ``--columns``
    (the log's names of the canonical columns, e.g. `example`; a name may hold spaces and brackets:
    ``--columns i_a="Phase A [A]"``) and ``--units`` (help `units_help`)."""
    p.add_argument(
        "--config",
        default=None,
        help=f'TOML with {tables} tables; [log] also says how the file is written: format = "vesc", '
        "delimiter, header_row, decimal (default: none, found from the file)",
    )
    add_key_values_flag(
        p,
        "--columns",
        "CANONICAL=NAME",
        f'column map, e.g. {example} or i_a="Phase A [A]" (default: the canonical names, also with a unit '
        "suffix such as 'Time [ms]')",
    )
    add_key_values_flag(p, "--units", "COLUMN=UNIT", units_help)


def key_values(items, flag: str, example: str = "u_d=Ud") -> dict[str, str]:
    """``{key: value}`` of KEY=VALUE words given to `flag` (a value keeps its inner spaces and brackets;
    quotes around it are dropped); a word without ``=`` is refused in one line."""
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ParameterError(f"{flag} {item}: not KEY=VALUE; write e.g. {flag} {example}.")
        value = value.strip()
        if len(value) > 1 and value[0] == value[-1] and value[0] in "\"'":
            value = value[1:-1]
        out[key.strip()] = value
    return out


def log_reading(args, allowed: set, command: str, readable=None):
    """``(columns, units, dialect, [log] table)`` of a command that reads a log: the ``--config`` file's
    ``[columns]``, ``[units]`` and ``[log]`` tables under ``--columns`` and ``--units`` (which win), and the
    file's dialect from ``[log]``
    ([`pmsmjax.io.log_formats.reader_options`][pmsmjax.io.log_formats.reader_options]; `readable`: the
    canonical columns the command reads, for a format preset). A ``[log]`` key outside `allowed` and the
    reader keys is refused, naming the keys `command` takes."""
    from pmsmjax.io.log_formats import READER_KEYS, reader_options

    cfg = {"columns": {}, "units": {}, "log": {}}
    if getattr(args, "config", None) is not None:
        from pmsmjax.io.toml_parser import read_toml

        path = existing_file(args.config, "--config", "config file")
        data = read_toml(path, f"log config {path}")
        unknown = sorted(set(data) - set(cfg))
        if unknown:
            raise ParameterError(
                f"log config {path}: unknown tables {unknown}; {command} reads [columns], [units] and [log]."
            )
        for table in cfg:
            if not isinstance(data.get(table, {}), dict):
                raise ParameterError(f"log config {path}: {table} must be a table, [{table}].")
            cfg[table] = dict(data.get(table, {}))
    keys = set(allowed) | set(READER_KEYS)
    bad = sorted(set(cfg["log"]) - keys)
    if bad:
        raise ParameterError(
            f"[log] table: unknown keys {bad}; allowed for {command}: {', '.join(sorted(keys))}."
        )
    columns = {**cfg["columns"], **key_values(args.columns, "--columns")}
    units = {**cfg["units"], **key_values(args.units, "--units", "time=ms")}
    dialect, columns, units = reader_options(cfg["log"], columns, units, readable=readable)
    return columns, units, dialect, cfg["log"]


def number(
    unit: str = "",
    *,
    minimum: float | None = None,
    maximum: float | None = None,
    above: bool = False,
    integer: bool = False,
    example: str | None = None,
):
    """An argparse ``type``: a finite number (an ``int`` with ``integer=True``) in ``unit``, at least
    `minimum` (greater than it with ``above=True``) and at most `maximum`."""
    of = f" of {unit}" if unit else ""
    in_unit = f" {unit}" if unit else ""
    kind = "whole number" if integer else "number"

    def convert(text: str):
        try:
            value = int(text) if integer else float(text)
        except ValueError:
            hint = f", e.g. {example}" if example else ""
            raise argparse.ArgumentTypeError(f"{text!r} is not a {kind}{of}: give one{hint}") from None
        if not math.isfinite(value):
            hint = f", e.g. {example}" if example else ""
            raise argparse.ArgumentTypeError(f"{text} is not a finite {kind}{of}: give one{hint}")
        if minimum is not None and (value <= minimum if above else value < minimum):
            sign = ">" if above else ">="
            raise argparse.ArgumentTypeError(
                f"{plain(value)}{in_unit} is too small: give a value {sign} {plain(minimum)}{in_unit}"
            )
        if maximum is not None and value > maximum:
            raise argparse.ArgumentTypeError(
                f"{plain(value)}{in_unit} is too large: give a value <= {plain(maximum)}{in_unit}"
            )
        return value

    convert.__name__ = kind
    return convert


def real(unit: str = "", example: str | None = None):
    """Any finite number in ``unit`` (negative allowed: a reverse speed, a generating load)."""
    return number(unit, example=example)


def positive(unit: str = "", maximum: float | None = None):
    """A finite number > 0 in ``unit``."""
    return number(unit, minimum=0.0, above=True, maximum=maximum)


def nonnegative(unit: str = "", maximum: float | None = None):
    """A finite number >= 0 in ``unit``."""
    return number(unit, minimum=0.0, maximum=maximum)


def count(minimum: int = 1, maximum: int | None = None):
    """A whole number >= ``minimum`` (and <= ``maximum``)."""
    return number(minimum=minimum, maximum=maximum, integer=True)


def flag(dest: str) -> str:
    """The flag of an argparse ``dest`` as the user typed it: ``load_time_s`` -> ``--load-time-s``."""
    return "--" + dest.replace("_", "-")


def output_folder(path, name: str = "--out") -> Path:
    """Refuse an output folder that cannot be made or written, before any work: an existing file (not a
    folder) at ``path`` or on its way, or a nearest existing folder the user may not write into.
    Nothing is created. Returns ``Path(path)``."""
    from pmsmjax.io.logs import check_output_folder

    path = check_output_folder(path, name)
    existing = next((p for p in (path, *path.parents) if p.exists()), Path("."))
    if not os.access(existing, os.W_OK | os.X_OK):
        raise ParameterError(
            f"{name} {path}: folder {existing} is not writable by you: choose a folder you can write to."
        )
    return path


def output_file(path, name: str) -> Path:
    """Refuse an output file path that is a folder or whose folder does not exist, before any work."""
    path = Path(path)
    if path.is_dir():
        raise ParameterError(f"{name} {path} is a folder: give a file name, e.g. {path / 'results.json'}.")
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise ParameterError(f"{name} {path}: folder {folder} does not exist; create it or write elsewhere.")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise ParameterError(f"{name} {path}: folder {folder} is not writable by you: write elsewhere.")
    return path


def existing_file(path, name: str, what: str = "file") -> Path:
    """Refuse a path that is not an existing file (missing, or a folder)."""
    path = Path(path)
    if not path.is_file():
        state = "is a folder" if path.is_dir() else "does not exist"
        raise ParameterError(f"{name} {path}: the {what} {state}; check the path.")
    return path


def user_terms(err: ParameterError, terms: dict[str, str]) -> ParameterError:
    """``err`` with the library's names replaced by the user's (``{"Drive.n_substeps": "--substeps"}``)."""
    text = str(err)
    for internal, user in terms.items():
        text = text.replace(internal, user)
    return ParameterError(text)
