"""Named columns of a CSV table and their assembly into a rectangular grid: what the point and inductance
readers share. A careless file is refused in one line naming it."""

from pathlib import Path

import numpy as np

from pmsmjax.spec.validation import ParameterError

__all__ = ["distinct", "read_csv_columns", "rows_to_grid"]


def read_csv_columns(path, required, where: str, optional=(), binary_hint: str = "") -> dict:
    """``{name: (n,) float array}`` of the columns `required` (and of `optional` ones present) of the CSV
    ``path``; ``#`` lines are comments. Values may be ``nan`` (a hole). ``binary_hint`` ends the refusal of
    a file that is not text (where the binary form of the table is read)."""
    try:
        text = Path(path).read_bytes().decode("utf-8-sig")  # an editor's byte-order mark is not the header's
    except UnicodeDecodeError as err:
        raise ParameterError(
            f"{where}: not a text file (byte {err.start} is not UTF-8){binary_hint}."
        ) from None
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise ParameterError(
            f"{where} is empty: it needs the header {','.join(required)} and one row per point."
        )
    header = [h.strip() for h in lines[0].split(",")]
    missing = [c for c in required if c not in header]
    if missing:
        raise ParameterError(
            f"{where} lacks the column(s) {', '.join(missing)} (header: {','.join(header)}): the header must "
            f"name {','.join(required)}."
        )
    try:
        rows = np.array([[float(x) for x in ln.split(",")] for ln in lines[1:]], dtype=float)
    except ValueError as err:
        raise ParameterError(f"{where}: a value is not a number ({err}).") from err
    if rows.ndim != 2 or rows.shape[1] != len(header):
        raise ParameterError(f"{where}: every row needs {len(header)} values, as many as the header names.")
    names = [*required, *(c for c in optional if c in header)]
    return {c: rows[:, header.index(c)] for c in names}


def distinct(values: np.ndarray) -> np.ndarray:
    """The sorted distinct values of ``values`` (``np.unique`` without its first call's import of
    ``numpy.ma``, a fifth of reading a drive file with a map); NaNs are kept, each, at the end."""
    ordered = np.sort(values)
    first = np.ones(ordered.size, dtype=bool)
    first[1:] = ordered[1:] != ordered[:-1]
    return ordered[first]


def rows_to_grid(i_d, i_q, values: dict, where: str, dtypes: dict | None = None):
    """``(i_d (n_d,), i_q (n_q,), {name: (n_d, n_q)})`` of rows that fill a rectangular grid, one row per
    point in any order; refused otherwise. ``dtypes``: ``{name: dtype}`` of grids that are not float."""
    if np.isnan(i_d).any() or np.isnan(i_q).any():
        raise ParameterError(f"{where}: a current (i_d or i_q) is NaN: every row needs its grid point.")
    axis_d, axis_q = distinct(i_d), distinct(i_q)
    if len(i_d) != axis_d.size * axis_q.size:
        raise ParameterError(
            f"{where}: {len(i_d)} rows do not fill the {axis_d.size} x {axis_q.size} grid of its distinct "
            'i_d and i_q values: give one row per grid point, or flux_map_format = "points" for scattered '
            "points."
        )
    j, k = np.searchsorted(axis_d, i_d), np.searchsorted(axis_q, i_q)
    if distinct(j * axis_q.size + k).size != len(i_d):
        raise ParameterError(f"{where}: a grid point appears twice: give one row per (i_d, i_q).")
    out = {}
    for name, column in values.items():
        grid = np.empty((axis_d.size, axis_q.size), dtype=(dtypes or {}).get(name, float))
        grid[j, k] = column
        out[name] = grid
    return axis_d, axis_q, out
