"""The dialect of a CSV log as instruments and firmware tools write it: its delimiter, decimal mark and
header row, given or found from the file's first lines.

Accepted:

- delimiters: comma, semicolon, tab, or runs of spaces and tabs (``whitespace``);
- a preamble above the header: ``key,value`` lines of an instrument, blank lines, comment lines starting
  with ``#`` or ``%`` (blank and comment lines are skipped between data rows too);
- a delimiter after the last field of the header and of every row (VESC Tool writes one);
- decimal commas (``0,5``) on request, with a delimiter other than the comma.

**Finding the header.** Without ``header_row`` the header is the first line whose fields are all names
(none reads as a number) followed, past blank and comment lines, by a row of numbers (or empty fields) with
the same field count; the delimiter is the one of comma, semicolon, tab and whitespace that makes such a
pair earliest in the file (the most fields on a tie). A file where no delimiter makes one is read as a plain
CSV: the first line that is not blank or a comment is a comma-separated header, so its refusals name
that line. A semicolon, tab or whitespace file whose numbers have decimal commas is refused unless
``decimal = ","`` is given: ``1,5`` could also be two fields.
"""

import dataclasses
import itertools
from pathlib import Path

from pmsmjax.spec.validation import ParameterError

__all__ = [
    "CsvDialect",
    "CsvLayout",
    "DELIMITERS",
    "SNIFF_LINES",
    "find_layout",
    "split_fields",
    "is_comment",
]

#: Delimiter names a config may give (``[log] delimiter``) -> the delimiter (``" "``: runs of whitespace).
DELIMITERS = {",": ",", ";": ";", "\t": "\t", "tab": "\t", "whitespace": " ", " ": " "}
#: Lines read from the top of a file to find its header.
SNIFF_LINES = 400
#: Comment marks: a line starting with one (after blanks) is skipped.
COMMENT_MARKS = ("#", "%")


@dataclasses.dataclass(frozen=True)
class CsvDialect:
    """How a CSV log is written, as far as the user states it (None: found from the file).

    Attributes:
        delimiter: ``","``, ``";"``, ``"\\t"`` or ``" "`` (runs of spaces and tabs), or None.
        header_row: 1-based line of the header, or None.
        decimal: ``"."`` or ``","`` (then the delimiter is not a comma).
    """

    delimiter: str | None = None
    header_row: int | None = None
    decimal: str = "."


@dataclasses.dataclass(frozen=True)
class CsvLayout:
    """A CSV log's dialect as read: `delimiter` (``" "``: whitespace runs), `decimal`, `header_line`
    (1-based), `names` (the header's column names) and `trailing` (every line ends with a delimiter,
    whose empty last field is no column)."""

    delimiter: str
    decimal: str
    header_line: int
    names: list[str]
    trailing: bool = False


def is_comment(text: str) -> bool:
    """A blank line or a comment line (``#``, ``%``)."""
    t = text.lstrip()
    return not t or t[0] in COMMENT_MARKS


def split_fields(line: str, delimiter: str) -> list[str]:
    """The fields of ``line``, stripped of whitespace and quotes."""
    parts = line.split() if delimiter == " " else line.rstrip("\r\n").split(delimiter)
    return [p.strip().strip("\"'").strip() for p in parts]


def _number(s: str, decimal: str) -> bool:
    if decimal == ",":
        if "." in s:
            return False
        s = s.replace(",", ".")
    try:
        float(s)
    except ValueError:
        return False
    return True


def _names_line(fields: list[str]) -> bool:
    return any(fields) and not any(_number(f, ".") or _number(f, ",") for f in fields if f)


def _data_line(fields: list[str], decimal: str) -> bool:
    return any(fields) and all(not f or _number(f, decimal) for f in fields)


def _pair(content, delimiter: str, decimal: str):
    """``(index in content, field count)`` of the first header + data pair, or None."""
    for k in range(len(content) - 1):
        head = split_fields(content[k][1], delimiter)
        if not _names_line(head):
            continue
        row = split_fields(content[k + 1][1], delimiter)
        if len(row) == len(head) and _data_line(row, decimal):
            return k, len(head)
    return None


def _head(path: Path) -> list[str]:
    with open(path, encoding="utf-8-sig", newline=None) as f:
        return list(itertools.islice(f, SNIFF_LINES))


def find_layout(path: Path, dialect: CsvDialect | None = None) -> CsvLayout:
    """The layout of the CSV log at ``path``: `dialect`'s stated parts, the rest found (module docstring).
    Raises [`ParameterError`][pmsmjax.spec.validation.ParameterError] for an empty file, a header row
    beyond the file or on a blank line, and decimal commas not asked for."""
    dialect = dialect or CsvDialect()
    lines = _head(path)
    content = [(k + 1, s) for k, s in enumerate(lines) if not is_comment(s)]
    if not content:
        raise ParameterError(f"log file {path} is empty: it needs a header row and data rows.")
    if dialect.decimal == "," and dialect.delimiter == ",":
        raise ParameterError(
            f'log file {path}: [log] decimal = "," needs a delimiter other than the comma: set [log] '
            'delimiter = ";" (or "tab", "whitespace"), as the file is written.'
        )
    candidates = [dialect.delimiter] if dialect.delimiter else [",", ";", "\t", " "]
    if dialect.decimal == ",":
        candidates = [d for d in candidates if d != ","]
    if dialect.header_row is not None:
        return _stated_header(path, lines, content, dialect, candidates)
    found = []
    for order, d in enumerate(candidates):
        pair = _pair(content, d, dialect.decimal)
        if pair is not None:
            found.append((pair[0], -pair[1], order, d))
    if not found:
        if dialect.decimal == ".":
            _refuse_decimal_commas(path, content, candidates)
        line_no, text = content[0]
        return _layout(line_no, text, dialect.delimiter or ",", dialect.decimal)
    k, _, _, d = min(found)
    if dialect.decimal == "." and d != ",":
        _refuse_decimal_commas(path, content[k:], [d])
    return _layout(content[k][0], content[k][1], d, dialect.decimal)


def _layout(line_no: int, text: str, delimiter: str, decimal: str) -> CsvLayout:
    names = split_fields(text, delimiter)
    trailing = delimiter != " " and len(names) > 1 and not names[-1] and all(names[:-1])
    return CsvLayout(delimiter, decimal, line_no, names[:-1] if trailing else names, trailing)


def _stated_header(path, lines, content, dialect, candidates) -> CsvLayout:
    n = dialect.header_row
    if n > len(lines) or is_comment(lines[n - 1]):
        what = "beyond the first lines read" if n > len(lines) else "blank or a comment"
        raise ParameterError(
            f"log file {path}: [log] header_row = {n} is {what}: give the 1-based line of the row naming the "
            "columns."
        )
    after = [s for line_no, s in content if line_no > n][:1]
    best = None
    for d in candidates:
        head = split_fields(lines[n - 1], d)
        ok = bool(after) and len(split_fields(after[0], d)) == len(head)
        if best is None or (ok, len(head)) > best[0]:
            best = ((ok, len(head)), d)
    return _layout(n, lines[n - 1], best[1], dialect.decimal)


def _refuse_decimal_commas(path, content, candidates) -> None:
    """Refuse a file whose numbers look like decimal commas (``0,5`` between semicolons) unasked: the rows
    after the first header + data pair under a non-comma delimiter with decimal commas."""
    for d in candidates:
        pair = None if d == "," else _pair(content, d, ",")
        if pair is None:
            continue
        for line_no, text in content[pair[0] + 1 : pair[0] + 21]:
            sample = next((f for f in split_fields(text, d) if "," in f and _number(f, ",")), None)
            if sample is not None:
                name = {";": ";", "\t": "tab", " ": "whitespace"}[d]
                raise ParameterError(
                    f"log file {path}, line {line_no}: numbers like {sample!r} have a decimal comma, or the "
                    f'comma splits fields: if decimal commas, set [log] decimal = "," (and delimiter = '
                    f'"{name}") in the --config file; else write the file with one delimiter.'
                )
