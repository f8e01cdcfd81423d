"""Cutting a log into equal shooting windows (shared by the electrical and mechanical fits).

A window of ``W`` intervals covers samples ``s .. s + W``; consecutive windows share their boundary
sample (window j ends where window j+1 starts). Equal lengths let every window run in one ``vmap``'d
scan; the few samples after the last whole window are not used (at most ``W - 1`` of them).
"""

import numpy as np

from pmsmjax.spec.validation import ParameterError

__all__ = ["window_layout", "interval_windows", "sample_windows"]


def window_layout(n_samples: int, target: int) -> tuple[int, int]:
    """``(n_windows, W)``: about ``target`` intervals per window, windows covering the log evenly."""
    n_intervals = n_samples - 1
    if target < 1 or n_intervals < target:
        raise ParameterError(
            f"the log has {n_samples} samples, too few for a window of {target} intervals: record a longer "
            "log or choose shorter windows."
        )
    n_windows = max(1, round(n_intervals / target))
    return n_windows, n_intervals // n_windows


def interval_windows(x: np.ndarray, n_windows: int, W: int) -> np.ndarray:
    """Per-interval values ``(N-1, ...)`` -> ``(n_windows, W, ...)``."""
    return x[: n_windows * W].reshape((n_windows, W) + x.shape[1:])


def sample_windows(x: np.ndarray, n_windows: int, W: int) -> np.ndarray:
    """Per-sample values ``(N, ...)`` -> ``(n_windows, W + 1, ...)`` (boundary samples repeated)."""
    idx = np.arange(n_windows)[:, None] * W + np.arange(W + 1)[None, :]
    return x[idx]
