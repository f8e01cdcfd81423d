"""The winding's thermal network from a logged heat run: ``R_th``, ``C_th`` and the ambient of the one-node
network [`pmsmjax.machines.thermal`][pmsmjax.machines.thermal] simulates,
``C_th dT/dt = 1.5 R(T) |i_dq|^2 - (T - T_amb) / R_th``, from a log with a ``temperature_c`` column.

**Data.** The log is cut into thermal points: each capture of a log recorded in bursts, and pieces of at
most ``point_s`` of a continuous log. A point gives its mean time, its mean logged temperature (the
temperature sensor's noise averaged over its rows) and its mean ``|i_dq|^2`` (A^2, amplitude-invariant:
the true currents after the sensor errors are taken out).

**The loss between points is held** from a point to the next: the operating point the drive holds between
two captures is the one captured (a heat run holds its load, or repeats one pattern, between captures; a
change of load just after a capture is then exact). The loss depends on the temperature through
``R(T) = R (1 + alpha (T - T_ref))``, so over each hold the network is linear in ``T``:

``dT/dt = a T + b``, ``a = (1.5 R alpha m - 1 / R_th) / C_th``,
``b = (1.5 R (1 - alpha T_ref) m + T_amb / R_th) / C_th``,

and is advanced exactly, ``T(t + h) = T_eq + (T(t) - T_eq) e^{a h}``, ``T_eq = -b / a`` (``a < 0``: a
loss that grows faster with temperature than the cooling would run away, and is refused).

**Fit.** Output error: the network is run from the first point's temperature (an unknown) through every
hold, and its temperatures at the points are compared with the logged means. The unknowns are
``log R_th``, ``log C_th`` (positive), the ambient (unless given) and the first temperature; SciPy's
Levenberg-Marquardt; the covariance ``s^2 (J^T J)^{-1}`` with ``s^2`` the residuals' variance (the points'
noise is independent); 95 % intervals are Student t with the residual degrees of freedom, in log space for
``R_th`` and ``C_th``.

**What the log must hold.** ``R_th`` is the temperature rise per watt and ``C_th`` the time constant's
share, so the log must span a good part of the time constant ``R_th C_th`` (a heat run: heating, and
better also cooling); a short log gives wide intervals and the parameters are then reported not
identifiable. R and alpha are those of the electrical fit: the loss is per ampere as sensor a reads it,
so an error of sensor a's absolute gain ``g`` scales the loss by ``g`` and ``R_th`` by ``1 / g``.
"""

import math

import numpy as np
from scipy import optimize, stats

from pmsmjax.spec.validation import ParameterError

__all__ = ["thermal_points", "fit_thermal_network", "temperature_report", "REL_TOL"]

#: R_th and C_th are identifiable when their relative standard error is below this.
REL_TOL = 0.05


def thermal_points(time, temperature_c, i_sq, segments, point_s: float = 1.0) -> dict:
    """The thermal points of the module docstring.

    Args:
        time: ``(N,)`` s. temperature_c: ``(N,)`` logged winding temperature, degC.
        i_sq: ``(N,)`` true ``|i_dq|^2``, A^2. segments: ``(S + 1,)`` capture bounds (rows).
        point_s: Longest point, s.

    Returns:
        ``{"time", "temperature_c", "i_sq", "rows"}``: ``(P,)`` arrays.
    """
    out = {"time": [], "temperature_c": [], "i_sq": [], "rows": []}
    for a, b in zip(segments[:-1], segments[1:], strict=True):
        pieces = max(1, math.ceil((time[b - 1] - time[a]) / point_s))
        for part in np.array_split(np.arange(a, b), pieces):
            out["time"].append(time[part].mean())
            out["temperature_c"].append(temperature_c[part].mean())
            out["i_sq"].append(i_sq[part].mean())
            out["rows"].append(part.size)
    return {k: np.asarray(v) for k, v in out.items()}


def _run(points, r_th, c_th, ambient_c, first_c, R, alpha, reference_c):
    """Network temperatures at the points, degC (module docstring)."""
    m = points["i_sq"]
    a = (1.5 * R * alpha * m - 1.0 / r_th) / c_th
    if np.any(a >= 0.0):
        raise FloatingPointError("thermal runaway")
    b = (1.5 * R * (1.0 - alpha * reference_c) * m + ambient_c / r_th) / c_th
    T = np.empty_like(m)
    T[0] = first_c
    h = np.diff(points["time"])
    for j in range(h.size):
        eq = -b[j] / a[j]
        T[j + 1] = eq + (T[j] - eq) * math.exp(a[j] * h[j])
    return T


#: A fitted temperature (the ambient, the first point's) is identifiable below this standard error, K.
TEMPERATURE_STDERR_K = 1.0


def _entry(value, se, unit, dof, log_space=False, identifiable=True):
    q = stats.t.ppf(0.975, max(dof, 1))
    if log_space:  # se is of log(value)
        ci = [value * math.exp(-q * se), value * math.exp(q * se)]
        se = value * se
    else:
        ci = [value - q * se, value + q * se]
    ok = identifiable and math.isfinite(se)
    return {
        "value": float(value),
        "stderr": float(se) if math.isfinite(se) else None,
        "ci95": [float(c) for c in ci] if ok else [None, None],
        "unit": unit,
        "identifiable": bool(ok),
    }


def fit_thermal_network(
    points: dict, R: float, alpha: float, reference_c: float, ambient_c: float | None = None,
    source: str = "log",
) -> dict:  # fmt: skip
    """Fit ``R_th``, ``C_th`` (and the ambient) to the thermal points (module docstring).

    Args:
        points: [`thermal_points`][tuning.identify.thermal_network_fit.thermal_points].
        R: Resistance at ``reference_c``, ohm. alpha: Its temperature coefficient, 1/K.
        reference_c: The temperature R is stated at, degC.
        ambient_c: The ambient (coolant) temperature, degC, when known; fitted when None.
        source: A name for messages.

    Returns:
        ``{"r_th_k_per_w", "c_th_j_per_k", "time_constant_s", "ambient_c", "initial_c", "residual_rms_k",
        "points", "note"}``, each parameter with value, standard error, 95 % interval and identifiability.

    Raises:
        ParameterError: For too few points, a log without heating, or a fit that does not converge.
    """
    T, m = points["temperature_c"], points["i_sq"]
    n_free = 3 if ambient_c is None else 2
    if T.size < n_free + 3:
        raise ParameterError(
            f"{source}: {T.size} thermal point(s) (captures, or {T.size} s of log) are too few for the "
            "thermal network: record a heat run over a few thermal time constants in 6 or more captures."
        )
    loss = 1.5 * R * (1.0 + alpha * (T - reference_c)) * m
    if np.max(loss) <= 0.0:
        raise ParameterError(f"{source}: the log carries no current, so nothing heats the winding.")
    # Start: the rise per watt at the hottest point, and a time constant of a third of the log.
    amb0 = float(np.min(T)) if ambient_c is None else float(ambient_c)
    r0 = max((float(np.max(T)) - amb0) / max(float(np.max(loss)), 1e-9), 1e-3)
    tau0 = max((points["time"][-1] - points["time"][0]) / 3.0, 1.0)
    x0 = [math.log(r0), math.log(tau0 / r0), T[0]] + ([amb0] if ambient_c is None else [])

    def unpack(x):
        return math.exp(x[0]), math.exp(x[1]), (x[3] if ambient_c is None else ambient_c), x[2]

    def residuals(x):
        r_th, c_th, amb, first = unpack(x)
        try:
            return _run(points, r_th, c_th, amb, first, R, alpha, reference_c) - T
        except (FloatingPointError, OverflowError):
            return np.full(T.size, 1e6)

    sol = optimize.least_squares(residuals, x0, method="lm", xtol=1e-12, ftol=1e-12)
    if not sol.success or not np.all(np.isfinite(sol.x)):
        raise ParameterError(f"{source}: the thermal-network fit did not converge ({sol.message}).")
    r = residuals(sol.x)
    dof = T.size - len(x0)
    s2 = float(r @ r) / max(dof, 1)
    cov = s2 * np.linalg.pinv(sol.jac.T @ sol.jac)
    se = np.sqrt(np.abs(np.diag(cov)))
    r_th, c_th, amb, first = unpack(sol.x)
    ok = lambda j: bool(se[j] < REL_TOL)  # se of a logarithm is the relative standard error
    tau_se = math.sqrt(max(cov[0, 0] + cov[1, 1] + 2.0 * cov[0, 1], 0.0))
    out = {
        "r_th_k_per_w": _entry(r_th, se[0], "K/W", dof, log_space=True, identifiable=ok(0)),
        "c_th_j_per_k": _entry(c_th, se[1], "J/K", dof, log_space=True, identifiable=ok(1)),
        "time_constant_s": _entry(r_th * c_th, tau_se, "s", dof, True, identifiable=tau_se < REL_TOL),
        "initial_c": _entry(first, se[2], "degC", dof, identifiable=se[2] < TEMPERATURE_STDERR_K),
    }
    if ambient_c is None:
        out["ambient_c"] = _entry(amb, se[3], "degC", dof, identifiable=se[3] < TEMPERATURE_STDERR_K)
    else:
        out["ambient_c"] = {"value": float(ambient_c), "unit": "degC", "given": True}
    span = points["time"][-1] - points["time"][0]
    out |= {
        "residual_rms_k": float(math.sqrt(float(r @ r) / T.size)),
        "points": int(T.size),
        "note": (
            f"one-node network fitted to {T.size} points over {span:.4g} s (the loss held from a point to "
            "the next), the loss 1.5 R(T) |i_dq|^2 per ampere as sensor a reads it; 95 % intervals Student t "
            f"with {dof} degrees of freedom"
        ),
    }
    return out


def temperature_report(errors, corrected: dict, segments, ambient_c: float | None = None) -> dict:
    """``params.json``'s ``temperature`` entry: the coefficients of the stator-frame fit and the thermal
    network fitted on the currents with the sensor errors taken out.

    Args:
        errors: The [`SensorErrors`][tuning.identify.sensor_errors.SensorErrors] of a log with a temperature
            column (its summary holds ``temperature``).
        corrected: The corrected SI columns
            ([`corrected_columns`][tuning.identify.sensor_errors.corrected_columns]): ``time``, ``i_a``,
            ``i_b``, ``i_c``, ``temperature_c``.
        segments: ``(S + 1,)`` capture bounds (rows).
        ambient_c: The ambient, degC, when known (else fitted).

    Returns:
        The coefficients' entry with ``thermal_network`` added (or, when the log cannot give it, a note
        saying why in its place).
    """
    report = dict(errors.summary["temperature"])
    i_sq = (2.0 / 3.0) * (corrected["i_a"] ** 2 + corrected["i_b"] ** 2 + corrected["i_c"] ** 2)
    points = thermal_points(corrected["time"], corrected["temperature_c"], i_sq, segments)
    R, alpha = report["R"]["value"], report["r_temp_coeff_per_k"]["value"]
    try:
        report["thermal_network"] = fit_thermal_network(
            points, R, alpha, report["reference_temperature_c"], ambient_c, errors.summary["log"]["source"]
        )
    except ParameterError as err:
        report["thermal_network"] = {"identifiable": False, "note": str(err)}
    return report
