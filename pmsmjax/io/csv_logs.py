"""The CSV log reader behind [`read_log`][pmsmjax.io.logs.read_log]: streamed, so that its peak memory is
about the parsed columns plus one block of text (``python -m benchmarks.log_reader_memory``).

A CSV log has a header row naming the columns and one row per sample below it; the delimiter, the decimal
mark and the header row are stated or found ([`pmsmjax.io.csv_dialect`][pmsmjax.io.csv_dialect]: comma,
semicolon, tab or whitespace; a preamble above the header). Blank lines and comment lines (``#``, ``%``)
are skipped; whitespace around names and values is ignored and an empty field reads as NaN (which
[`check_columns`][pmsmjax.io.logs.check_columns] then locates). A byte-order mark is read as none.
"""

import io
import itertools
import os
from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np

from pmsmjax.io.csv_dialect import CsvDialect, CsvLayout, find_layout, is_comment
from pmsmjax.spec.validation import ParameterError

__all__ = ["CSV_CHUNK_LINES", "RowLines", "read_csv_columns", "read_csv_names"]


#: Lines parsed at a time by the CSV reader: bounds the text held in memory (about 8 MB of Python strings
#: for 70-byte lines) while keeping NumPy's per-call overhead negligible.
CSV_CHUNK_LINES = 65_536


class RowLines(Mapping):
    """Row index -> 1-based file line of a CSV log, stored as the rows where the offset between the two
    changes (blank and comment lines between rows), not one entry per row."""

    def __init__(self, n_rows: int, starts: list[int], offsets: list[int]):
        self._n = n_rows
        self._starts = np.asarray(starts, dtype=np.int64)
        self._offsets = np.asarray(offsets, dtype=np.int64)

    def __getitem__(self, row: int) -> int:
        if not 0 <= row < self._n:
            raise KeyError(row)
        k = int(np.searchsorted(self._starts, row, side="right")) - 1
        return int(row + self._offsets[k])

    def __len__(self) -> int:
        return self._n

    def __iter__(self):
        return iter(range(self._n))


def _csv_header(path: Path, dialect: CsvDialect | None) -> CsvLayout:
    """The layout of the CSV log at ``path`` with its header's names checked."""
    layout = find_layout(path, dialect)
    names = layout.names
    line = layout.delimiter.join(names)
    if all(_is_number(n.replace(",", ".")) for n in names):
        raise ParameterError(
            f"log file {path}: line {layout.header_line} {line.strip()!r} is data, not a header: add a "
            "header row naming the columns, e.g. 'time,u_d,u_q'."
        )
    if any(not n for n in names):
        raise ParameterError(
            f"log file {path}: the header {line.strip()!r} (line {layout.header_line}) has an empty column "
            "name (check for a doubled delimiter); name every column."
        )
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise ParameterError(f"log file {path}: column(s) {', '.join(dupes)} appear twice in the header.")
    return layout


def _open_text(path: Path):
    return open(path, encoding="utf-8-sig", newline=None)


def read_csv_names(path: Path, dialect: CsvDialect | None = None) -> dict[str, None]:
    """``{name: None}`` for every column of the CSV log's header (the data is not read)."""
    try:
        layout = _csv_header(path, dialect)
    except UnicodeDecodeError as err:
        raise ParameterError(f"log file {path}: not a text CSV file ({err}).") from err
    return dict.fromkeys(layout.names)


def read_csv_columns(
    path: Path,
    wanted: Iterable[str] | None = None,
    required: Iterable[str] = (),
    chunk_lines: int | None = None,
    dialect: CsvDialect | None = None,
) -> tuple[dict[str, np.ndarray | None], RowLines]:
    """Header + delimited rows -> ``({name: column}, row index -> 1-based file line)``.

    Streams the file `chunk_lines` lines at a time (default `CSV_CHUNK_LINES`) into one preallocated
    float64 array per column (sized from the file's bytes per line, grown by half when short), so the
    peak memory is about the parsed columns plus one chunk of text. Only the columns named in `wanted`
    (all with None) are parsed, the others map to None; every row's field count is checked against the
    header all the same. With a name of `required` missing from the header nothing is parsed (every
    column maps to None, for [`check_columns`][pmsmjax.io.logs.check_columns] to refuse). `dialect`: the
    delimiter, decimal mark and header row as far as stated
    ([`CsvDialect`][pmsmjax.io.csv_dialect.CsvDialect]; the rest is found).
    """
    chunk_lines = CSV_CHUNK_LINES if chunk_lines is None else int(chunk_lines)
    try:
        layout = _csv_header(path, dialect)
        names, header_line = layout.names, layout.header_line
        with _open_text(path) as f:
            for _ in itertools.islice(f, header_line):
                pass
            if any(r not in names for r in required):
                return dict.fromkeys(names), RowLines(0, [0], [header_line + 1])
            wanted = names if wanted is None else [n for n in names if n in set(wanted)]
            cols = [names.index(n) for n in wanted]
            columns, row_lines = _parse_rows(path, f, layout, cols, chunk_lines)
    except UnicodeDecodeError as err:
        raise ParameterError(f"log file {path}: not a text CSV file ({err}).") from err
    out: dict[str, np.ndarray | None] = dict.fromkeys(names)
    out.update(zip(wanted, columns, strict=True))
    return out, row_lines


def _fields(line: str, delimiter: str) -> int:
    return len(line.split()) if delimiter == " " else line.count(delimiter) + 1


def _parse_rows(path: Path, f, layout: CsvLayout, cols: list[int], chunk_lines: int):
    """The data rows of the open CSV ``f`` (after its header) -> (list of (N,) float64 columns ``cols``,
    `RowLines`)."""
    names, header_line, delim = layout.names, layout.header_line, layout.delimiter
    n_fields = len(names) + layout.trailing
    size = os.fstat(f.fileno()).st_size
    buf = None
    n = 0  # rows stored
    line_no = header_line  # file lines consumed
    starts, offsets = [0], [header_line + 1]  # row r sits on line r + offset

    def mark(row: int, line: int) -> None:
        """Row ``row`` is on file line ``line``: record a change of offset."""
        if line - row != offsets[-1]:
            if starts[-1] == row:
                offsets[-1] = line - row
            else:
                starts.append(row)
                offsets.append(line - row)

    while True:
        lines = list(itertools.islice(f, chunk_lines))
        if not lines:
            break
        skip = [is_comment(s) for s in lines]

        if any(skip):
            kept = []
            for k, (s, drop) in enumerate(zip(lines, skip, strict=True)):
                if not drop:
                    if k == 0 or skip[k - 1]:
                        mark(n + len(kept), line_no + k + 1)
                    kept.append(s)
        else:
            kept = lines
            mark(n, line_no + 1)
        bad = next((k for k, s in enumerate(kept) if _fields(s, delim) != n_fields), None)
        if bad is not None:
            row = n + bad
            line = RowLines(row + 1, starts, offsets)[row]
            text = kept[bad].rstrip("\r\n")
            n_got = _fields(text, delim) - (layout.trailing and text.endswith(delim))
            ends = " and a delimiter after the last" if layout.trailing else ""
            raise ParameterError(
                f"log file {path}, line {line}: {n_got} fields but the header names {len(names)} "
                f"columns{ends} ({', '.join(names)}): every row needs one value per column."
            )
        line_no += len(lines)
        if not kept:
            continue
        if layout.decimal == ",":
            kept = [s.replace(",", ".") for s in kept]
        block = _parse_block(kept, cols, None if delim == " " else delim)
        if buf is None:
            per_line = max(sum(map(len, lines)) / len(lines), 1.0)
            buf = np.empty((len(cols), max(int(1.02 * size / per_line) + 16, len(kept))), np.float64)
        if n + len(kept) > buf.shape[1]:
            grown = np.empty((len(cols), max(int(1.5 * buf.shape[1]), n + len(kept))), np.float64)
            grown[:, :n] = buf[:, :n]
            buf = grown
        buf[:, n : n + len(kept)] = block.T
        n += len(kept)
        del lines, kept, block
    if buf is None:
        return [np.zeros(0) for _ in cols], RowLines(0, starts, offsets)
    if n < 0.9 * buf.shape[1]:  # an overestimate worth giving back
        buf = buf[:, :n].copy()
    return [buf[j, :n] for j in range(len(cols))], RowLines(n, starts, offsets)


def _parse_block(lines: list[str], cols: list[int], delimiter: str | None = ",") -> np.ndarray:
    """``(len(lines), len(cols))`` float64 of the CSV data ``lines`` (`delimiter` None: whitespace runs);
    a field that is empty or no number reads as NaN (which [`check_columns`][pmsmjax.io.logs.check_columns]
    then locates)."""
    if not cols:
        return np.zeros((len(lines), 0))
    try:
        return np.loadtxt(
            lines, delimiter=delimiter, dtype=np.float64, comments=None, ndmin=2, usecols=cols, quotechar=None
        )
    except ValueError:
        # The slow reader, only for a chunk with a bad field: it turns such fields into NaN.
        return np.genfromtxt(
            io.StringIO("".join(s if s.endswith("\n") else s + "\n" for s in lines)),
            delimiter=delimiter,
            dtype=np.float64,
            comments=None,
            ndmin=2,
            usecols=cols,
        ).reshape(len(lines), len(cols))


def _is_number(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True
