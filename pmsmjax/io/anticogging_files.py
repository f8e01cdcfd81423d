"""Anticogging tables as files: ``anticogging.csv``, one row per bin over one electrical revolution, columns
``theta_e_rad`` (the bin's electrical angle, ``2 pi j / N``) and ``iq_a`` (the feed-forward q current, A).

A CSV beside ``gains.toml`` rather than a table inside it: the gains file holds named positive scalars (its
reader refuses anything else), the anticogging table is a signed curve over the angle that one plots,
compares with a cogging measurement, or loads into a drive's firmware as an array.
"""

import csv
import io
import math
from pathlib import Path

import numpy as np

from pmsmjax.spec.validation import ParameterError

__all__ = ["write_anticogging_csv", "read_anticogging_csv", "COLUMNS"]

COLUMNS = ("theta_e_rad", "iq_a")


def write_anticogging_csv(path, iq_a) -> Path:
    """Write the table ``iq_a`` (``(N,)`` A over one electrical revolution) to ``path``, atomically."""
    from pmsmjax.io.logs import atomic_write

    iq = np.asarray(iq_a, float).reshape(-1)
    angles = 2.0 * np.pi * np.arange(iq.size) / iq.size

    def write(f):
        f.write(",".join(COLUMNS) + "\n")
        for theta, value in zip(angles, iq, strict=True):
            f.write(f"{float(theta)!r},{float(value)!r}\n")

    return atomic_write(path, write, mode="w")


def read_anticogging_csv(path) -> np.ndarray:
    """``(N,)`` the q currents (A) of an anticogging CSV, checked: the two columns, at least 2 rows, finite
    values, and the angles ``2 pi j / N`` (bins over one electrical revolution, in order)."""
    path = Path(path)
    where = f"anticogging table {path}"
    if not path.is_file():
        raise ParameterError(
            f"{where} does not exist: give the anticogging.csv pmsmjax tune --anticogging wrote."
        )
    rows = list(csv.reader(io.StringIO(path.read_text())))
    if not rows or tuple(c.strip() for c in rows[0]) != COLUMNS:
        raise ParameterError(
            f"{where}: the header must be {','.join(COLUMNS)}, got {rows[0] if rows else 'nothing'}."
        )
    try:
        values = np.array([[float(x) for x in r] for r in rows[1:] if r], float)
    except ValueError as err:
        raise ParameterError(f"{where}: every value must be a number ({err}).") from None
    if values.ndim != 2 or values.shape[0] < 2 or values.shape[1] != 2 or not np.all(np.isfinite(values)):
        raise ParameterError(f"{where}: give at least 2 rows of two finite numbers (theta_e_rad, iq_a).")
    n = values.shape[0]
    if not np.allclose(values[:, 0], 2.0 * math.pi * np.arange(n) / n, atol=1e-9):
        raise ParameterError(
            f"{where}: theta_e_rad must be the {n} bins 2 pi j / {n} over one electrical revolution, in "
            "order."
        )
    return values[:, 1]
