"""Logged data in and out: CSV, NumPy ``.npz`` and MATLAB ``.mat`` logs, checked before anything compiles.

A log is a set of equally long 1-D numeric columns, one of which is usually the time in seconds:

- CSV: a header row naming the columns, then one row per sample; comma, semicolon, tab or whitespace
  separated, a preamble above the header, decimal commas on request
  ([`pmsmjax.io.csv_dialect`][pmsmjax.io.csv_dialect]). Whitespace around names and values is ignored, an
  empty field reads as NaN (and is then reported as such).
- ``.npz``: one array per column, the key is the column name (``np.savez(path, time=t, u_d=...)``).
- ``.mat``: one variable per column (``save log.mat time u_d u_q`` in MATLAB, v4 to v7.3); row or column
  vectors ([`pmsmjax.io.mat_files`][pmsmjax.io.mat_files]).

[`read_log`][pmsmjax.io.logs.read_log] returns the requested columns as float64 NumPy arrays after
[`check_columns`][pmsmjax.io.logs.check_columns] has checked them: required columns present, no NaN/inf, at
least two rows, equal lengths, time strictly increasing. Every failure is a
[`ParameterError`][pmsmjax.spec.validation.ParameterError] naming the column, the row and the fix. Extra
columns are allowed and ignored.

Writers go through [`atomic_write`][pmsmjax.io.logs.atomic_write]: the data is written to a temporary file in
the destination folder and renamed over the target only once complete, so an interrupted or failed run never
leaves a half-written file (``os.replace`` is atomic within one file system).
"""

import difflib
import io
import os
import tempfile
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path

import numpy as np

from pmsmjax.io.csv_dialect import CsvDialect
from pmsmjax.io.csv_logs import read_csv_columns, read_csv_names
from pmsmjax.io.mat_files import mat_names, mat_rows, read_mat
from pmsmjax.spec.validation import ParameterError

__all__ = [
    "read_log",
    "log_rows",
    "check_columns",
    "column_names",
    "misspelt_columns",
    "atomic_write",
    "write_csv_atomic",
    "LOG_SUFFIXES",
]

#: File suffixes [`read_log`][pmsmjax.io.logs.read_log] understands.
LOG_SUFFIXES = (".csv", ".txt", ".npz", ".mat")


# --------------------------------------------------------------------------------------------------
# reading
# --------------------------------------------------------------------------------------------------
def read_log(
    path: str | os.PathLike,
    required: Iterable[str] = ("time",),
    optional: Iterable[str] = (),
    *,
    time: str | None = "time",
    unused: list | None = None,
    dialect: CsvDialect | None = None,
) -> dict[str, np.ndarray]:
    """Read and check a logged data file; returns ``{column: (N,) float64 array}``.

    **Arguments:**

    - `path`: a ``.csv`` (or ``.txt``), ``.npz`` or ``.mat`` file (see the module docstring for layouts).
    - `required`: column names that must be present.
    - `optional`: column names returned when present.
    - `time`: name of the time column (s) that must be strictly increasing, or ``None`` for no such check.
    - `dialect`: a CSV file's delimiter, decimal mark and header row as far as stated
      ([`CsvDialect`][pmsmjax.io.csv_dialect.CsvDialect]; the rest is found from the file).

    Only the required and the present optional columns are returned (in that order); other columns are
    ignored, and their names appended to `unused` when a list is given (to report them, or to catch a
    misspelt optional column with [`misspelt_columns`][pmsmjax.io.logs.misspelt_columns]). Raises
    [`ParameterError`][pmsmjax.spec.validation.ParameterError] for a missing file, an unknown format, a
    missing required column, NaN/inf values, fewer than two rows, unequal lengths or a time column that does
    not increase.
    """
    path = Path(path)
    required, optional = tuple(required), tuple(optional)
    if not path.is_file():
        raise ParameterError(f"log file {str(path)!r} does not exist: check the path.")
    suffix = path.suffix.lower()
    line_offset = None
    if suffix in (".csv", ".txt"):
        raw, line_offset = read_csv_columns(path, required + optional, required, dialect=dialect)
    elif suffix == ".npz":
        raw = _read_npz(path)
    elif suffix == ".mat":
        raw = read_mat(path)
    else:
        raise ParameterError(
            f"log file {path}: unknown format {path.suffix!r}; use one of {', '.join(LOG_SUFFIXES)} "
            "(CSV with a header row, NumPy .npz with one key per column, MATLAB .mat with one variable "
            "per column)."
        )
    if unused is not None:
        unused.extend(c for c in raw if c not in required and c not in optional)
    return check_columns(raw, required, optional, time=time, source=f"log {path}", line_offset=line_offset)


def column_names(path: str | os.PathLike, dialect: CsvDialect | None = None) -> list[str]:
    """Every column name in the log at ``path`` (for hints about misspelt columns, and to map names with
    units); ``[]`` if it cannot be read ([`read_log`][pmsmjax.io.logs.read_log] reports why)."""
    path = Path(path)
    csv = lambda p: read_csv_names(p, dialect)
    readers = {".csv": csv, ".txt": csv, ".npz": _read_npz, ".mat": mat_names}
    reader = readers.get(path.suffix.lower())
    if reader is None or not path.is_file():
        return []
    try:
        raw = reader(path)
    except (ParameterError, UnicodeDecodeError, OSError):
        return []
    return list(raw[0] if isinstance(raw, tuple) else raw)


def log_rows(path: str | os.PathLike) -> int | None:
    """The number of rows of the log at ``path`` without parsing it, or None if it cannot be told (a
    missing file, an unknown format: [`read_log`][pmsmjax.io.logs.read_log] reports why).

    A CSV file's is an upper bound: its lines after the first, blank and comment lines included (counted
    in 1 MiB blocks). An ``.npz`` file's is its longest array's element count, from the arrays' headers;
    a ``.mat`` file's its longest variable's, from ``scipy.io.whosmat`` (v7.3: the HDF5 datasets' shapes).
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if not path.is_file():
        return None
    try:
        if suffix in (".csv", ".txt"):
            lines, last = 0, b"\n"
            with open(path, "rb") as f:
                while block := f.read(1 << 20):
                    lines += block.count(b"\n")
                    last = block[-1:]
            return max(lines + (last != b"\n") - 1, 0)
        if suffix == ".npz":
            import zipfile

            longest = 0
            with zipfile.ZipFile(path) as z:
                for name in z.namelist():
                    with z.open(name) as f:
                        major, _ = np.lib.format.read_magic(f)
                        header = {1: np.lib.format.read_array_header_1_0}.get(
                            major, np.lib.format.read_array_header_2_0
                        )
                        shape, _, _ = header(f)
                    longest = max(longest, int(np.prod(shape, dtype=np.int64)))
            return longest
        if suffix == ".mat":
            return mat_rows(path)
    except Exception:
        return None
    return None


def misspelt_columns(unused, absent, cutoff: float = 0.75) -> list[tuple[str, str]]:
    """``[(column, known name)]`` for each unused column that looks like a known column the log lacks
    (``omega`` for ``omega_m``, ``omgea_m``): a misspelt optional column silently changes what is computed,
    so callers refuse it with the hint. Case-insensitive, `difflib.get_close_matches` at `cutoff`."""
    absent = list(absent)
    lower = {a.lower(): a for a in absent}
    out = []
    for col in unused:
        match = difflib.get_close_matches(col.lower(), list(lower), n=1, cutoff=cutoff)
        if match:
            out.append((col, lower[match[0]]))
    return out


def check_columns(
    columns: Mapping[str, object],
    required: Iterable[str] = ("time",),
    optional: Iterable[str] = (),
    *,
    time: str | None = "time",
    source: str = "log",
    line_offset: Mapping[int, int] | int | None = None,
) -> dict[str, np.ndarray]:
    """Check a mapping of columns as [`read_log`][pmsmjax.io.logs.read_log] does and return the selected
    float64 columns.

    `source` names the data in messages; `line_offset` maps a row index to its line in a text file (an
    ``int`` offset or a mapping from row to line) so messages can point at the file line as well.
    """
    required, optional = tuple(required), tuple(optional)
    missing = [c for c in required if c not in columns]
    if missing:
        present = ", ".join(sorted(columns)) or "none"
        hints = []
        for c in missing:
            close = difflib.get_close_matches(c, list(columns), n=1, cutoff=0.6)
            if close:
                hints.append(f"{close[0]!r} looks like {c!r}: rename it")
        raise ParameterError(
            f"{source}: missing column(s) {', '.join(missing)}; present: {present}. "
            f"Add the missing column(s) (needed: {', '.join(required)}"
            + (f"; optional: {', '.join(optional)}" if optional else "")
            + ")"
            + (f"; {'; '.join(hints)}" if hints else "")
            + "."
        )
    names = list(required) + [c for c in optional if c in columns and c not in required]
    out: dict[str, np.ndarray] = {}
    for name in names:
        out[name] = _as_column(columns[name], name, source)

    lengths = {name: v.shape[0] for name, v in out.items()}
    if len(set(lengths.values())) > 1:
        detail = ", ".join(f"{n}: {k}" for n, k in lengths.items())
        raise ParameterError(
            f"{source}: columns have different lengths ({detail}); every column needs one value per row."
        )
    n_rows = next(iter(lengths.values()), 0)
    if names and n_rows < 2:
        raise ParameterError(
            f"{source}: {n_rows} row(s); a log needs at least 2 rows (the value of row k is held until row "
            "k+1): record more samples."
        )

    for name, v in out.items():
        bad = ~np.isfinite(v)
        if bad.any():
            row = int(np.argmax(bad))
            raise ParameterError(
                f"{source}: column {name!r} is {_describe(v[row])} at row {row}{_where(row, line_offset)}: "
                "every value must be a finite number; fill the gap (interpolate) or cut the log before it."
            )

    if time is not None and time in out:
        t = out[time]
        dt = np.diff(t)
        bad = ~(dt > 0)
        if bad.any():
            row = int(np.argmax(bad)) + 1
            raise ParameterError(
                f"{source}: time column {time!r} must be strictly increasing but row {row}"
                f"{_where(row, line_offset)} has {time} = {float(t[row])!r} after {float(t[row - 1])!r} "
                f"at row {row - 1}: "
                "sort the rows by time and drop duplicate samples."
            )
    return out


def _as_column(value, name: str, source: str) -> np.ndarray:
    try:
        arr = np.asarray(value)
    except Exception as err:  # pragma: no cover - exotic objects
        raise ParameterError(f"{source}: column {name!r} cannot be read as numbers ({err}).") from err
    if arr.dtype.kind not in "biuf":
        raise ParameterError(
            f"{source}: column {name!r} holds {arr.dtype} values, not real numbers: store it as a numeric "
            "vector (no text, no complex values)."
        )
    arr = np.squeeze(arr)
    if arr.ndim == 0:
        arr = arr.reshape(1)
    if arr.ndim != 1:
        raise ParameterError(
            f"{source}: column {name!r} has shape {np.shape(value)}; a column must be a vector (one value "
            "per row): store each signal as its own 1-D column."
        )
    return arr.astype(np.float64, copy=False)  # a float64 column is returned as it is, not copied


def _describe(x: float) -> str:
    return "NaN (empty or not a number)" if np.isnan(x) else f"{x} (infinite)"


def _where(row: int, line_offset) -> str:
    if line_offset is None:
        return ""
    line = line_offset.get(row) if isinstance(line_offset, Mapping) else row + line_offset
    return "" if line is None else f" (file line {line})"


def _read_npz(path: Path) -> dict[str, np.ndarray]:
    try:
        with np.load(path, allow_pickle=False) as f:
            return {k: f[k] for k in f.files}
    except Exception as err:
        raise ParameterError(
            f"log file {path}: cannot read it as NumPy .npz ({err}); write it with "
            "np.savez(path, time=t, u_d=...)."
        ) from err


# --------------------------------------------------------------------------------------------------
# writing
# --------------------------------------------------------------------------------------------------
def atomic_write(path: str | os.PathLike, writer: Callable[[io.IOBase], None], mode: str = "wb") -> Path:
    """Write ``path`` atomically: ``writer(f)`` fills a temporary file in the same folder, then it is renamed.

    On any exception (or interrupt) the temporary file is removed and an existing ``path`` is left as it
    was. `mode` is ``"wb"`` (binary, e.g. ``np.savez``, ``scipy.io.savemat``) or ``"w"`` (text, UTF-8).
    The folder must exist. Returns ``Path(path)``.
    """
    if mode not in ("w", "wb"):
        raise ValueError(f"mode must be 'w' or 'wb', got {mode!r}")
    path = Path(path)
    folder = path.parent
    if not folder.is_dir():
        raise ParameterError(f"cannot write {path}: folder {folder} does not exist; create it first.")
    from pmsmjax.io.folder_lock import TEMP_PREFIX, TEMP_SUFFIX

    # The name pattern folder_lock.orphan_temporaries removes after a killed run.
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=f"{TEMP_PREFIX}{path.name}.", suffix=TEMP_SUFFIX)
    try:
        kwargs = {"encoding": "utf-8", "newline": ""} if mode == "w" else {}
        with os.fdopen(fd, mode, **kwargs) as f:
            writer(f)
            f.flush()
            os.fsync(f.fileno())
        # mkstemp creates the file 0600; give it the permissions a plain open() would have.
        os.chmod(tmp, _default_mode(path))
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    return path


def check_output_folder(path: str | os.PathLike, flag: str = "--out") -> Path:
    """Refuse an output folder that cannot be one, before any work: an existing file (not a folder) at
    ``path``, or on its way. Returns ``Path(path)``; the folder is created by the caller when it writes."""
    if not str(path).strip():
        raise ParameterError(f"{flag} is empty: give a folder name, e.g. {flag} runs (it is created).")
    path = Path(path)
    try:
        name_max = os.pathconf(path.anchor or ".", "PC_NAME_MAX")
    except (OSError, ValueError, AttributeError):
        name_max = 255
    long = next((part for part in path.parts if len(os.fsencode(part)) > name_max), None)
    if long is not None:
        raise ParameterError(
            f"{flag}: the folder name {long[:20]}... is {len(os.fsencode(long))} bytes long, more than the "
            f"{name_max} this file system allows: give a shorter name."
        )
    for p in (path, *path.parents):
        if p.is_symlink() and not p.exists():
            raise ParameterError(
                f"{flag} {path}: {p} is a symbolic link to {os.readlink(p)}, which does not exist; create "
                "that folder or give another folder name."
            )
        if p.exists() and not p.is_dir():
            raise ParameterError(
                f"{flag} {path}: {p} is an existing file, not a folder; give a folder name (it is created)."
            )
    return path


def _default_mode(path: Path) -> int:
    if path.exists():
        return path.stat().st_mode & 0o777
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


def write_csv_atomic(path: str | os.PathLike, columns: Mapping[str, object], *, fmt: str = "%.17g") -> Path:
    """Write equally long 1-D columns as a CSV file (header row, comma separated), atomically.

    `fmt` is the number format (default ``%.17g``: float64 values survive the round trip exactly).
    """
    if not columns:
        raise ParameterError(f"nothing to write to {path}: give at least one column.")
    names = list(columns)
    bad = [n for n in names if not n or "," in n or "\n" in n]
    if bad:
        raise ParameterError(f"column names {bad!r} cannot be written to CSV: use names without commas.")
    arrays = [np.asarray(columns[n], dtype=np.float64).reshape(-1) for n in names]
    lengths = {n: a.shape[0] for n, a in zip(names, arrays, strict=True)}
    if len(set(lengths.values())) > 1:
        raise ParameterError(f"cannot write {path}: columns have different lengths {lengths}.")
    table = np.stack(arrays, axis=1)

    def writer(f):
        np.savetxt(f, table, fmt=fmt, delimiter=",", header=",".join(names), comments="")

    return atomic_write(path, writer, mode="wb")
