"""Known temperature coefficients of R and psi_f in the identification fit.

With a logged winding temperature ``T`` (degC, the log's ``temperature_c``) and given coefficients, the models
of [`tuning.identify.electrical`][tuning.identify.electrical] and
[`tuning.identify.mechanical`][tuning.identify.mechanical] use, in each shooting window and each
equation-error block, ``R (1 + alpha (T_w - T_ref))`` and ``psi_f (1 + beta (T_w - T_ref))`` with ``T_w`` the
mean logged temperature over the window's samples. The fitted R and psi_f are then their values at ``T_ref``.
The coefficients are given, not fitted (copper: alpha = 0.00393 /K; NdFeB magnets: beta about -0.0012 /K).
"""

import math
from collections.abc import Mapping

import numpy as np

from pmsmjax.spec.validation import ParameterError

__all__ = ["KEYS", "check_coeffs", "scales"]

#: The keys of ``temperature_coeffs``: T_ref (degC), alpha of R (1/K), beta of psi_f (1/K).
KEYS = ("reference_temperature_c", "r_temp_coeff_per_k", "psi_f_temp_coeff_per_k")


def check_coeffs(coeffs) -> dict | None:
    """``{key: float}`` of a ``temperature_coeffs`` mapping (None stays None); refuses a missing or unknown
    key and a value that is not a finite number."""
    if coeffs is None:
        return None
    if not isinstance(coeffs, Mapping) or set(coeffs) != set(KEYS):
        got = sorted(coeffs) if isinstance(coeffs, Mapping) else repr(coeffs)
        raise ParameterError(
            f"temperature_coeffs must be a table with exactly {', '.join(KEYS)} (degC, 1/K, 1/K), got {got}."
        )
    out = {}
    for k in KEYS:
        v = coeffs[k]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ParameterError(f"temperature_coeffs[{k!r}] must be a finite number, got {v!r}.")
        out[k] = float(v)
    return out


def scales(temperature_c, starts, length: int, coeffs) -> tuple[np.ndarray, np.ndarray] | None:
    """``(R factor, psi_f factor)``, each ``(n,)``: ``1 + coeff (T_w - T_ref)`` with ``T_w`` the mean of
    ``temperature_c`` over rows ``starts[j] .. starts[j] + length`` (a window of ``length`` intervals); None
    when there is no temperature or no coefficients."""
    if temperature_c is None or coeffs is None:
        return None
    rows = np.asarray(starts, dtype=int)[:, None] + np.arange(length + 1)[None, :]
    dT = np.asarray(temperature_c, dtype=np.float64)[rows].mean(axis=1) - coeffs["reference_temperature_c"]
    return 1.0 + coeffs["r_temp_coeff_per_k"] * dT, 1.0 + coeffs["psi_f_temp_coeff_per_k"] * dT
