"""Magnet flux harmonics in the stator-frame fit (``pmsmjax identify --flux-harmonics 5,7``).

The model is [`pmsmjax.machines.harmonics`][pmsmjax.machines.harmonics]'s: phase ``x`` links
``A_k cos(k (theta_e - s_x) + phi_k)`` besides the fundamental, which amplitude-invariant Clarke turns into
the complex alpha-beta flux

    ``psi_h,ab = c_k e^{j k theta_e}`` (``k = 1 mod 3``, positive sequence) or
    ``conj(c_k e^{j k theta_e})`` (``k = 2 mod 3``, negative sequence),   ``c_k = A_k e^{j phi_k}`` (Wb).

The stator-frame equation of [`tuning.identify.stator_frame_fit`][tuning.identify.stator_frame_fit]
integrates the voltage over blocks, so the harmonics add ``psi_h,ab(theta_end) - psi_h,ab(theta_start)`` to
each block's flux change: linear in ``Re c_k`` and ``Im c_k``. With the encoder offset ``delta`` unknown
(``theta_e = theta_m - delta``) the linear start fits ``c_k e^{-j k delta}`` against ``e^{j k theta_m}``
(or its conjugate), linear as well, and turns it back by the fitted ``delta``; the Levenberg-Marquardt
refinement then takes ``Re c_k``, ``Im c_k`` with every other unknown. Amplitude and phase get their
intervals from the covariance of ``(Re c_k, Im c_k)`` by the delta method (the phase's interval is
meaningful while the amplitude is several standard errors from zero).

The harmonics do not scale with the winding temperature (the simulator's model: a warm magnet scales
``psi_f`` only) and do not depend on the current.
"""

import math

import numpy as np

__all__ = [
    "flux_ab",
    "dflux_ab",
    "start_columns",
    "rotate_start",
    "amplitude_phase",
    "harmonic_entries",
    "flux_harmonics_summary",
]


def flux_ab(theta: np.ndarray, orders, coeffs) -> np.ndarray:
    """``(N,)`` complex alpha-beta harmonic flux, Wb, at the electrical angles ``theta`` (rad), for the
    complex ``coeffs`` ``c_k = A_k e^{j phi_k}`` (Wb) of ``orders``."""
    psi = np.zeros(np.shape(theta), complex)
    for k, c in zip(orders, coeffs, strict=True):
        z = c * np.exp(1j * k * theta)
        psi = psi + (z if k % 3 == 1 else np.conj(z))
    return psi


def dflux_ab(theta: np.ndarray, orders, coeffs) -> np.ndarray:
    """``d psi_h,ab / d theta`` (complex, Wb/rad) at ``theta`` (rad): the harmonic back-EMF per electrical
    rad/s."""
    out = np.zeros(np.shape(theta), complex)
    for k, c in zip(orders, coeffs, strict=True):
        z = 1j * k * c * np.exp(1j * k * theta)
        out = out + (z if k % 3 == 1 else np.conj(z))
    return out


def start_columns(theta_m: np.ndarray, orders, change) -> list[np.ndarray]:
    """The linear start's complex columns for ``Re``, ``Im`` of ``c_k e^{-j k delta}`` per order: the
    flux change ``change(x) = x[end] - x[start]`` over each block of the basis at the measured angle
    ``theta_m`` (rad)."""
    cols = []
    for k in orders:
        if k % 3 == 1:
            z = np.exp(1j * k * theta_m)
            cols += [change(z), 1j * change(z)]
        else:
            w = np.exp(-1j * k * theta_m)
            cols += [change(w), -1j * change(w)]
    return cols


def rotate_start(values, orders, delta: float) -> np.ndarray:
    """``[Re c_k, Im c_k, ...]`` from the linear start's ``c_k e^{-j k delta}`` (same layout) and the
    encoder offset ``delta`` (rad)."""
    c = np.asarray(values[0::2]) + 1j * np.asarray(values[1::2])
    c = c * np.exp(1j * np.asarray(orders) * delta)
    return np.stack([c.real, c.imag], axis=1).ravel()


def amplitude_phase(re: float, im: float, cov2: np.ndarray) -> tuple[float, float, float, float]:
    """``(A, phi, se_A, se_phi)`` of ``A e^{j phi} = re + j im`` with the 2x2 covariance ``cov2`` (delta
    method); ``phi`` in ``(-pi, pi]``."""
    a = math.hypot(re, im)
    phi = math.atan2(im, re)
    if a == 0.0:
        return 0.0, 0.0, math.inf, math.inf
    ga = np.array([re, im]) / a
    gp = np.array([-im, re]) / a**2
    return a, phi, math.sqrt(max(ga @ cov2 @ ga, 0.0)), math.sqrt(max(gp @ cov2 @ gp, 0.0))


def _entry(value, stderr, unit, ok):
    finite = math.isfinite(stderr)
    ok = bool(ok and finite)
    return {
        "value": float(value),
        "stderr": float(stderr) if finite else None,
        "ci95": [float(value - 1.96 * stderr), float(value + 1.96 * stderr)] if ok else [None, None],
        "unit": unit,
        "identifiable": ok,
    }


def harmonic_entries(orders, re_im: np.ndarray, cov: np.ndarray, unit: str, rel_tol: float = 0.05) -> list:
    """``[{"order", "amplitude", "phase_rad"}, ...]``: each order's amplitude (``unit``) and phase (rad),
    with standard errors and 95 % intervals, from ``[Re, Im, ...]`` and their ``(2K, 2K)`` covariance; an
    amplitude is identifiable when its relative standard error is below ``rel_tol`` (the phase with it)."""
    out = []
    for j, k in enumerate(orders):
        a, phi, se_a, se_p = amplitude_phase(
            re_im[2 * j], re_im[2 * j + 1], cov[2 * j : 2 * j + 2, 2 * j : 2 * j + 2]
        )
        ok = math.isfinite(se_a) and se_a < rel_tol * a
        amp = _entry(a, se_a, unit, ok)
        phase = _entry(phi, se_p, "rad", ok)
        phase["value_deg"] = math.degrees(phi)
        out.append({"order": int(k), "amplitude": amp, "phase_rad": phase})
    return out


def flux_harmonics_summary(problem, p: np.ndarray, cov: np.ndarray) -> dict:
    """The ``flux`` entry of ``params.json``'s ``harmonics``: the orders' amplitudes (Wb) and phases (rad)
    of the stator-frame fit ``problem`` (its unknowns ``p``, their covariance ``cov``)."""
    j = problem.names.index(f"flux_{problem.flux_orders[0]}_re")
    n = 2 * len(problem.flux_orders)
    return {
        "orders": list(problem.flux_orders),
        "rows": harmonic_entries(problem.flux_orders, p[j : j + n], cov[j : j + n, j : j + n], "Wb"),
        "model": "psi_pm,x += A cos(k (theta_e - s_x) + phi) on phase x (axis s_x), fitted in the "
        "stator-frame voltage equation with the sensor errors",
    }
