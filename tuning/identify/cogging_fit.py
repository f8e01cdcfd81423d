"""Cogging torque from a logged shaft torque (``pmsmjax identify --cogging-orders 6,12``).

**Where the torque comes from.** Cogging is a torque at zero current, so it is seen only through a torque
balance. Two runs give one: a dynamometer that holds a slow speed while a torque sensor between it and the
motor logs the shaft torque ``T_L``, or a free-running slow run whose speed ripple times the inertia gives
the torque. This fit uses the first: at a held speed the balance is algebraic,
``T_L = T_e(i, theta_e) + T_cog(theta_e) - B w_m - T_coulomb sign(w_m)``, linear in the cogging's
amplitudes, with no derivative of a measured signal; the speed-ripple route needs the second derivative of
the measured angle (encoder quantisation and noise amplified by ``w^2``), the inertia ``J`` to a percent
(the cogging amplitude scales with it), and a run where nothing but cogging moves the speed, and the speed
loop that keeps a run slow removes the ripple it would measure. A log without ``T_L`` is refused in one
line.

**Model.** ``T_L = k_T T_e,model + sum_j (a_j sin(n_j theta_e) + b_j cos(n_j theta_e)) + c_+ [w_m > 0] +
c_- [w_m < 0] - B w_m`` (``C_j sin(n_j theta_e + phi_j)`` with ``a_j = C_j cos phi_j``, ``b_j = C_j sin
phi_j``, the model of [`pmsmjax.machines.harmonics`][pmsmjax.machines.harmonics]), with
``T_e,model = 1.5 p (psi_f(T) i_q + (L_d - L_q) i_d i_q) + 1.5 p Re(conj(i_ab) d psi_h,ab / d theta_e)``
from the stator-frame fit (the fundamental, the temperature coefficients and the flux harmonics, with the
currents and angle corrected by the identified sensor errors). ``k_T`` takes the torque's scale: the
currents are per ampere as sensor a reads it, so ``k_T = 1 / g_a`` is sensor a's absolute gain as the
torque sensor sees it; it is fitted when the logged torque varies (current steps), else held at 1. The
offsets take the friction and a torque-sensor offset per direction; ``B`` is fitted when the log has
speeds that separate it from them. Ordinary least squares; the covariance is the sandwich with Newey-West
lags ([`tuning.identify.uncertainty.covariance`][tuning.identify.uncertainty.covariance]); amplitudes and
phases get their intervals by the delta method.

The held speed is taken as the log's ``omega_m`` (a dynamometer holds it: no acceleration term); a run
whose speed varies by more than ``MAX_SPEED_RIPPLE`` of its mean within a capture is refused, as the
inertia torque would enter the fit.
"""

import math

import numpy as np

from pmsmjax.spec.validation import ParameterError
from tuning.identify.flux_harmonics_fit import dflux_ab, harmonic_entries
from tuning.identify.uncertainty import covariance

__all__ = ["electromagnetic_torque", "fit_cogging", "check_torque_column", "MAX_SPEED_RIPPLE"]

#: The largest speed variation (peak-to-peak over the mean |speed|) within a capture of a held-speed run.
MAX_SPEED_RIPPLE = 0.05
_SQRT3 = math.sqrt(3.0)


def check_torque_column(cols: dict, source: str) -> None:
    """Refuse, in one line, a cogging fit from a log without the shaft torque ``T_L`` (module docstring)."""
    if "T_L" not in cols:
        raise ParameterError(
            f"{source}: --cogging-orders needs the shaft torque T_L of a held-speed run (a torque sensor "
            "between the motor and the dynamometer); the speed ripple of a free-running run is not used (it "
            "needs the angle's second derivative and J): log T_L, or drop --cogging-orders."
        )


def _currents(cols: dict) -> np.ndarray:
    """Complex alpha-beta current, A, from the corrected phase currents."""
    i_a, i_b = cols["i_a"], cols["i_b"]
    return i_a + 1j * (i_a + 2.0 * i_b) / _SQRT3


def electromagnetic_torque(cols: dict, machine: dict, pole_pairs: int, reference_c: float) -> np.ndarray:
    """``(N,)`` electromagnetic torque of the identified machine, N m, from the corrected columns ``i_a``,
    ``i_b`` (A), ``theta_e`` (rad) and ``temperature_c`` (degC, when the fit has temperature
    coefficients); ``machine`` is the stator-frame fit's
    ([`SensorErrors.machine`][tuning.identify.sensor_errors.SensorErrors])."""
    th = cols["theta_e"]
    i_ab = _currents(cols)
    i_dq = i_ab * np.exp(-1j * th)
    psi_f = machine["psi_f"]
    if "psi_f_temp_coeff_per_k" in machine and "temperature_c" in cols:
        psi_f = psi_f * (1.0 + machine["psi_f_temp_coeff_per_k"] * (cols["temperature_c"] - reference_c))
    p = pole_pairs
    torque = 1.5 * p * (psi_f * i_dq.imag + (machine["L_d"] - machine["L_q"]) * i_dq.real * i_dq.imag)
    if "flux_harmonics" in machine:
        orders, coeffs = machine["flux_harmonics"]
        torque = torque + 1.5 * p * np.real(np.conj(i_ab) * dflux_ab(th, orders, coeffs))
    return torque


def _columns(cols: dict, torque: np.ndarray, orders, source: str):
    w = cols["omega_m"]
    th = cols["theta_e"]
    names, X = [], []
    for n in orders:
        X += [np.sin(n * th), np.cos(n * th)]
        names += [f"cog_{n}_sin", f"cog_{n}_cos"]
    for sign, label in ((1.0, "offset_forward_nm"), (-1.0, "offset_reverse_nm")):
        if np.any(np.sign(w) == sign):
            X.append((np.sign(w) == sign).astype(float))
            names.append(label)
    extra = [("k_T", torque), ("B", -w)]
    for name, col in extra:
        trial = np.stack([*X, col], axis=1)
        scaled = trial / np.maximum(np.linalg.norm(trial, axis=0), 1e-300)
        sv = np.linalg.svd(scaled, compute_uv=False)
        if sv[-1] > 1e-3 * sv[0]:
            X.append(col)
            names.append(name)
    if not np.any(np.abs(w) > 0):
        raise ParameterError(f"{source}: --cogging-orders needs the rotor turning (omega_m is zero).")
    return names, np.stack(X, axis=1)


def fit_cogging(cols: dict, machine: dict, pole_pairs: int, orders, segments, reference_c: float = 20.0,
                source: str = "log") -> dict:  # fmt: skip
    """Fit the cogging torque (module docstring).

    Args:
        cols: Corrected SI columns (``i_a``, ``i_b``, ``theta_e``, ``omega_m``, ``T_L``, and
            ``temperature_c``).
        machine: The stator-frame fit's machine (``psi_f``, ``L_d``, ``L_q``, temperature coefficients,
            ``flux_harmonics``).
        pole_pairs: Pole pairs.
        orders: Cogging orders per electrical revolution.
        segments: ``(S + 1,)`` first rows of the captures and the row count.
        reference_c: The temperature the machine's psi_f is stated at, degC.
        source: A name for messages.

    Returns:
        The ``cogging`` entry of ``params.json``'s ``harmonics``: ``orders``, ``rows`` (amplitude, N m, and
        phase, rad, with intervals), ``torque_scale`` (``k_T``), ``friction`` and ``residual_rms_nm``.

    Raises:
        ParameterError: Without ``T_L``, at standstill, or for a speed that is not held.
    """
    check_torque_column(cols, source)
    w = cols["omega_m"]
    for a, b in zip(segments[:-1], segments[1:], strict=True):
        seg = w[a:b]
        mean = float(np.mean(np.abs(seg)))
        if mean > 0 and float(np.ptp(seg)) > MAX_SPEED_RIPPLE * mean:
            raise ParameterError(
                f"{source}: --cogging-orders takes the shaft torque at a held speed, but the speed varies by "
                f"{float(np.ptp(seg)):.3g} rad/s around {mean:.3g} rad/s in the capture at row {a} (over "
                f"{100 * MAX_SPEED_RIPPLE:g} %): hold the speed with the dynamometer, or cut the log."
            )
    torque = electromagnetic_torque(cols, machine, pole_pairs, reference_c)
    names, X = _columns(cols, torque, orders, source)
    y = cols["T_L"] - (0.0 if "k_T" in names else torque)
    scale = np.maximum(np.linalg.norm(X, axis=0), 1e-300)
    x = np.linalg.lstsq(X / scale, y, rcond=None)[0] / scale
    r = y - X @ x
    n = r.size
    cov = covariance([(X, r, (1, n), 20)])[0]
    se = np.sqrt(np.abs(np.diag(cov)))
    k = 2 * len(orders)
    rows = harmonic_entries(orders, x[:k], cov[:k, :k], "N m")
    out = {
        "orders": [int(o) for o in orders],
        "rows": rows,
        "residual_rms_nm": float(np.sqrt(np.mean(r**2))),
        "model": "T_L = k_T T_e + sum C sin(n theta_e + phi) + offset per direction - B omega_m (held speed)",
        "source": "the logged shaft torque T_L at a held speed",
    }
    named = dict(zip(names, zip(x, se, strict=True), strict=True))
    if "k_T" in named:
        v, s = named["k_T"]
        out["torque_scale"] = {
            "value": float(v),
            "stderr": float(s),
            "ci95": [float(v - 1.96 * s), float(v + 1.96 * s)],
            "note": "the logged torque per unit of the model's (1 / sensor a's absolute gain as the torque "
            "sensor sees it)",
        }
    else:
        out["torque_scale"] = {"value": 1.0, "note": "held at 1: the log's torque does not vary enough"}
    out["friction"] = {
        n: {"value": float(v), "stderr": float(s)} for n, (v, s) in named.items() if not n.startswith("cog_")
        and n != "k_T"
    }  # fmt: skip
    return out
