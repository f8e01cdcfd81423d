"""The physical range of a Monte Carlo study's parameters: what a draw may not cross (a negative
resistance, inductance or inertia), counted, and clipped or refused as the study asks."""

import math

import numpy as np

from pmsmjax.spec.validation import ParameterError

__all__ = ["ABSOLUTE_PARAMETERS", "NONNEGATIVE", "CLIP_FRACTION", "lower_bound", "enforce_physical"]

#: Study parameters whose tolerance is an absolute half-width in their unit (signed, nominal possibly 0).
ABSOLUTE_PARAMETERS = ("current_sensor.offset_a",)
NONNEGATIVE = ("motor.psi_f", "motor.B")
#: Where ``nonphysical = "clip"`` puts a sample below its bound: this fraction of the nominal value
#: for parameters that must be > 0 (a zero inductance or inertia cannot be simulated), 0 for the others.
CLIP_FRACTION = 0.01


def lower_bound(name: str) -> tuple[float, bool]:
    """``(bound, strict)``: the physical range of ``name`` is ``> bound`` (strict) or ``>= bound``."""
    if name.startswith(("scenario.", *ABSOLUTE_PARAMETERS)):
        return -math.inf, False
    return 0.0, name not in NONNEGATIVE


def enforce_physical(samples: dict[str, np.ndarray], nominals: dict[str, float], mode: str) -> dict:
    """Count (and with ``mode="clip"`` clip) samples outside each parameter's physical range.

    **Returns:** ``{name: count}`` of non-physical samples; ``samples`` is clipped in place.
    Raises [`ParameterError`][pmsmjax.spec.validation.ParameterError] with ``mode="refuse"`` when any sample
    is non-physical.
    """
    counts = {}
    for name, x in samples.items():
        bound, strict = lower_bound(name)
        bad = (x <= bound) if strict else (x < bound)
        counts[name] = int(np.sum(bad))
        if counts[name] and mode == "clip":
            x[bad] = bound + CLIP_FRACTION * abs(nominals[name]) if strict else bound
    if mode == "refuse" and any(counts.values()):
        detail = ", ".join(f"{k}: {v}" for k, v in counts.items() if v)
        raise ParameterError(
            f"non-physical samples ({detail} of {len(next(iter(samples.values())))}) outside the "
            "physical range "
            "(> 0; >= 0 for psi_f and B): narrow the tolerance, use a lognormal distribution, or set "
            "nonphysical = 'clip' (--clip) to move them to the bound."
        )
    return counts
