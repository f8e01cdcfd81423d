"""Bands of a switching controller set for a chosen mean switching frequency (comparisons at equal
switching losses, the book, ch. 4).

A hysteresis-type controller (table DTC, hysteresis current control) switches at a frequency that follows
from its bands, its sample period and the operating point, while a PWM controller switches at its carrier
frequency. To compare them at equal mean switching frequency,
[`match_switching_frequency`][pmsmjax.jobs.equal_switching.match_switching_frequency] scales all of the
controller's bands by one factor ``k`` (keeping their ratio: the table DTC's torque and flux bands together)
and searches ``k`` so that the mean switching frequency over the last ``window_periods`` periods of a run
through ``scenario`` meets the target. The bands are array leaves, so every run reuses one compiled program.

The frequency falls with the bands roughly as a power law but in steps (a band change moves switching
instants by whole samples) and it cannot exceed ``1/(2 Ts)`` per leg, so the search works in
``log k`` (secant on ``log f``, safeguarded by bisection of the bracket) and stops within ``rel_tol`` of
the target or, failing that, at the closest run; the report says how close it got.
"""

import math

import jax
import numpy as np

from pmsmjax.analysis import metrics
from pmsmjax.assemble import part, with_parts
from pmsmjax.controllers.dtc import SwitchingTableDTC
from pmsmjax.controllers.hysteresis import HysteresisCurrentControl
from pmsmjax.drive import Drive
from pmsmjax.simulate import simulate
from pmsmjax.spec.validation import ParameterError

#: Controller class -> the band leaves scaled together.
BAND_LEAVES = {
    SwitchingTableDTC: ("torque_band_nm", "flux_band_wb"),
    HysteresisCurrentControl: ("band_a",),
}

__all__ = ["BAND_LEAVES", "match_switching_frequency", "scale_bands", "window_switching_frequency_hz"]


def _band_names(drive: Drive) -> tuple[str, ...]:
    names = BAND_LEAVES.get(type(drive.controller))
    if names is None:
        raise ParameterError(
            f"{type(drive.controller).__name__} has no bands to set a switching frequency with; "
            f"choose a controller among {', '.join(c.__name__ for c in BAND_LEAVES)}."
        )
    return names


def scale_bands(drive: Drive, factor) -> Drive:
    """``drive`` with every band of its controller ([`BAND_LEAVES`][pmsmjax.jobs.equal_switching.BAND_LEAVES])
    multiplied by ``factor``."""
    paths = [f"controller.{name}" for name in _band_names(drive)]
    return with_parts(drive, {path: part(drive, path) * factor for path in paths})


def window_switching_frequency_hz(drive: Drive, scenario, window_periods: int) -> float:
    """Mean switching frequency (Hz) of the legs over the last ``window_periods`` periods of a run."""
    trace = simulate(drive, scenario)
    duties = jax.device_get(trace.duties)[-window_periods:]
    return float(metrics.switching_frequency_hz(duties, drive.Ts))


def match_switching_frequency(
    drive: Drive,
    scenario,
    target_hz: float,
    window_periods: int,
    *,
    rel_tol: float = 0.01,
    max_runs: int = 16,
    factor_range: tuple[float, float] = (1.0 / 64.0, 64.0),
) -> dict:
    """Scale the bands of ``drive`` so its mean switching frequency over the window meets ``target_hz``.

    **Arguments:**

    - `drive`: a drive whose controller has bands
      ([`BAND_LEAVES`][pmsmjax.jobs.equal_switching.BAND_LEAVES]).
    - `scenario`: the run it is judged on (the comparison's scenario).
    - `target_hz`: the mean switching frequency wanted, Hz (a PWM drive's carrier frequency).
    - `window_periods`: the last periods of the run over which the frequency is measured.
    - `rel_tol`: stop once within this fraction of the target.
    - `max_runs`: simulations at most. `factor_range`: the band factors searched.

    **Returns:** ``{"factor", "switching_frequency_hz", "drive", "runs": [(factor, f_sw Hz), ...],
    "converged"}`` for the run closest to the target.
    """
    names = _band_names(drive)
    limit = 0.5 / drive.Ts
    if not 0 < target_hz < limit:
        raise ParameterError(
            f"target switching frequency {target_hz:g} Hz must lie in (0, {limit:g}) Hz, the most a leg "
            f"sampled every {drive.Ts * 1e6:g} us can switch."
        )
    lo, hi = (math.log(f) for f in factor_range)
    runs = []

    def measure(log_k):
        f = window_switching_frequency_hz(scale_bands(drive, math.exp(log_k)), scenario, window_periods)
        runs.append((math.exp(log_k), f))
        return f

    # Bracket: f falls as the bands widen, so f(lo) > target > f(hi) once bracketed.
    x0, f0 = 0.0, measure(0.0)
    x_lo, x_hi = (lo, 0.0) if f0 < target_hz else (0.0, hi)
    step = 1.0 if f0 > target_hz else -1.0
    x1 = x0 + step * math.log(2.0)
    while len(runs) < max_runs and abs(f0 / target_hz - 1.0) > rel_tol:
        x1 = min(max(x1, lo), hi)
        f1 = measure(x1)
        if abs(f1 / target_hz - 1.0) <= rel_tol:
            break
        if f1 > target_hz:
            x_lo = max(x_lo, x1)
        else:
            x_hi = min(x_hi, x1)
        # Secant on log f against log k; bisection when it leaves the bracket or stalls.
        if f1 > 0 and f0 > 0 and f1 != f0 and x1 != x0:
            slope = (math.log(f1) - math.log(f0)) / (x1 - x0)
            guess = x1 + (math.log(target_hz) - math.log(f1)) / slope if slope < 0 else None
        else:
            guess = None
        x0, f0 = x1, f1
        x1 = guess if guess is not None and x_lo < guess < x_hi else 0.5 * (x_lo + x_hi)
        if x_hi - x_lo < 1e-4:
            break
    factor, f_best = min(runs, key=lambda r: abs(math.log(r[1] / target_hz)) if r[1] > 0 else np.inf)
    return {
        "factor": factor,
        "switching_frequency_hz": f_best,
        "target_hz": target_hz,
        "band_leaves": list(names),
        "drive": scale_bands(drive, factor),
        "runs": runs,
        "converged": abs(f_best / target_hz - 1.0) <= rel_tol,
    }
