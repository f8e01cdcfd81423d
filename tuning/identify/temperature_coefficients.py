"""The report of R and psi_f as functions of the winding temperature, fitted by the stator-frame fit
([`tuning.identify.stator_frame_fit`][tuning.identify.stator_frame_fit]) from a log with a ``temperature_c``
column: ``R(T) = R (1 + alpha (T - T_ref))``, ``psi_f(T) = psi_f (1 + beta (T - T_ref))`` as
[`pmsmjax.machines.thermal`][pmsmjax.machines.thermal] simulates them.

A coefficient is seen through the change of R (or psi_f) across the logged temperatures: a log whose
temperature barely moves cannot give it, and the report says so instead of printing a number. R and psi_f at
``T_ref`` are extrapolations when ``T_ref`` lies outside the logged range; their intervals include that.
"""

import math

import numpy as np

__all__ = ["temperature_summary", "MIN_TEMPERATURE_SPAN_K", "REL_TOL"]

#: A log must span at least this many kelvin for the coefficients to be reported identifiable.
MIN_TEMPERATURE_SPAN_K = 10.0
#: A coefficient is identifiable when its relative standard error is below this.
REL_TOL = 0.05


def _entry(value: float, stderr: float, unit: str, identifiable: bool) -> dict:
    ok = identifiable and math.isfinite(stderr)
    return {
        "value": float(value),
        "stderr": float(stderr) if math.isfinite(stderr) else None,
        "ci95": [float(value - 1.96 * stderr), float(value + 1.96 * stderr)] if ok else [None, None],
        "unit": unit,
        "identifiable": bool(ok),
    }


def temperature_summary(problem, p: np.ndarray, se: np.ndarray, log) -> dict:
    """The ``temperature`` entry of ``params.json``'s ``sensor_errors`` (module docstring).

    Args:
        problem: The [`StatorFrameProblem`][tuning.identify.stator_frame_fit.StatorFrameProblem] fitted.
        p: ``(n,)`` fitted unknowns (SI). se: ``(n,)`` their standard errors.
        log: The [`SensorLog`][tuning.identify.sensor_errors.SensorLog] (its ``temperature_c``, degC).

    Returns:
        ``{"reference_temperature_c", "logged_range_c", "R", "psi_f", "r_temp_coeff_per_k",
        "psi_f_temp_coeff_per_k", "note"}``: R and psi_f at the reference, each with value, standard error,
        95 % interval and identifiability.
    """
    low, high = float(np.min(log.temperature_c)), float(np.max(log.temperature_c))
    span_ok = high - low >= MIN_TEMPERATURE_SPAN_K
    entries = {}
    units = {"R": "ohm", "psi_f": "Wb", "r_temp_coeff_per_k": "1/K", "psi_f_temp_coeff_per_k": "1/K"}
    for name, unit in units.items():
        j = problem.names.index(name)
        coefficient = name.endswith("_per_k")
        rel = se[j] / max(abs(p[j]), 1e-300)
        entries[name] = _entry(p[j], se[j], unit, rel < REL_TOL and (span_ok or not coefficient))
    note = f"R and psi_f at {problem.reference_c:g} degC; the log spans {low:.1f} to {high:.1f} degC" + (
        "" if span_ok else f" (under {MIN_TEMPERATURE_SPAN_K:g} K: too little for the coefficients)"
    )
    return {
        "reference_temperature_c": problem.reference_c,
        "logged_range_c": [low, high],
        **entries,
        "note": note,
    }
