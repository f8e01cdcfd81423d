"""Cutting a log into equal shooting windows and equation-error blocks (shared by the electrical and
mechanical fits), none of which spans a time gap between two captures of a burst log.

A log is one or more captures (segments): capture ``s`` is rows ``bounds[s]:bounds[s + 1]``
([`tuning.identify.log_columns.segment_bounds`][tuning.identify.log_columns.segment_bounds]). A window of
``W`` intervals starting at row ``a`` covers samples ``a .. a + W``; inside a capture consecutive windows
share their boundary sample (window j ends where window j+1 starts). All windows have the same ``W`` so every
window runs in one ``vmap``'d scan; the few samples after the last whole window of a capture are not used (at
most ``W - 1`` of them). The interval from the last row of a capture to the first of the next spans the gap
and belongs to no window and no block.
"""

import numpy as np

from pmsmjax.spec.validation import ParameterError

__all__ = ["window_layout", "segment_windows", "block_starts", "interval_windows", "sample_windows"]


def window_layout(n_samples: int, target: int) -> tuple[int, int]:
    """``(n_windows, W)``: about ``target`` intervals per window, covering a one-capture log evenly."""
    n_intervals = n_samples - 1
    if target < 1 or n_intervals < target:
        raise ParameterError(
            f"the log has {n_samples} samples, too few for a window of {target} intervals: record a longer "
            "log or choose shorter windows."
        )
    n_windows = max(1, round(n_intervals / target))
    return n_windows, n_intervals // n_windows


def segment_windows(bounds, target: int) -> tuple[np.ndarray, int]:
    """``(starts, W)``: the first row of every window and their common length in intervals.

    One capture: the layout of [`window_layout`][tuning.identify.windows.window_layout]. Several:
    ``W = min(target, intervals of the shortest capture)`` and ``floor(n_s / W)`` windows in a capture of
    ``n_s`` intervals, laid from its first row."""
    bounds = np.asarray(bounds, dtype=int)
    if bounds.size <= 2:
        n_w, W = window_layout(int(bounds[-1] - bounds[0]), target)
        return int(bounds[0]) + W * np.arange(n_w), W
    n_int = np.diff(bounds) - 1
    W = int(min(target, n_int.min()))
    if W < 1:
        raise ParameterError(f"a capture of {int(n_int.min()) + 1} sample(s) holds no window: drop it.")
    starts = [a + W * np.arange(n // W) for a, n in zip(bounds[:-1], n_int, strict=True)]
    return np.concatenate(starts).astype(int), W


def block_starts(bounds, block: int) -> np.ndarray:
    """First rows of the equation-error blocks of ``block`` intervals, laid from the first row of each capture
    (``floor(n_s / block)`` of them in a capture of ``n_s`` intervals)."""
    bounds = np.asarray(bounds, dtype=int)
    n_int = np.diff(bounds) - 1
    starts = [a + block * np.arange(max(n, 0) // block) for a, n in zip(bounds[:-1], n_int, strict=True)]
    return np.concatenate(starts).astype(int)


def interval_windows(x: np.ndarray, starts, W: int) -> np.ndarray:
    """Per-interval values ``(N-1, ...)`` -> ``(n_windows, W, ...)``; `starts`: the windows' first rows, or
    their number (windows laid end to end from row 0)."""
    return x[_rows(starts, W, 0)]


def sample_windows(x: np.ndarray, starts, W: int) -> np.ndarray:
    """Per-sample values ``(N, ...)`` -> ``(n_windows, W + 1, ...)`` (boundary samples repeated); `starts` as
    in [`interval_windows`][tuning.identify.windows.interval_windows]."""
    return x[_rows(starts, W, 1)]


def _rows(starts, W: int, extra: int) -> np.ndarray:
    starts = W * np.arange(starts) if np.ndim(starts) == 0 else np.asarray(starts, dtype=int)
    return starts[:, None] + np.arange(W + extra)[None, :]
