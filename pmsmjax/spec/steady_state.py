"""Steady states of a PMSM drive before any run: is an operating point reachable within the voltage and
current limits? Pure Python on a mapping of motor values (a drive file's ``[motor]``), so every command
checks a request before JAX starts.

Steady state of the dq model (the book, ch. 1) at mechanical speed ``w`` (rad/s) under load ``T_L``
(N m) with d-axis current ``i_d`` (A)::

    T_e = T_L + B w,  i_q = T_e / (1.5 p (psi_f + (L_d - L_q) i_d)),
    u_d = R i_d - w_e L_q i_q,  u_q = R i_q + w_e (L_d i_d + psi_f),  w_e = p w,

(``1.5`` is the three-phase torque factor; a multi-phase motor's mapping carries ``n_phases`` and its
``n/2`` replaces it: 3 for six phases, 2.5 for five), and the point is reachable when
``|u_dq| <= U_lim`` (the modulator's linear limit, ``U_dc / sqrt 3`` for SVPWM) and ``|i_dq| <= I_max``
(the controller's current limit). With i_d = 0 control the top speed at a load follows by bisection;
with field weakening any ``-I_max <= i_d <= 0`` may be used. The equations are the machines' own,
[`pmsmjax.machines.dq_equations`][pmsmjax.machines.dq_equations] (written once for floats, NumPy and JAX),
here on the linear model. How a finished run met these limits is
[`pmsmjax.analysis.operating_point.run_flags`][pmsmjax.analysis.operating_point.run_flags].
"""

import math
from collections.abc import Mapping

import numpy as np

from pmsmjax.machines import dq_equations as dq
from pmsmjax.spec.validation import ParameterError, plain

__all__ = [
    "steady_point",
    "top_speed_rpm",
    "field_weakening_top_speed_rpm",
    "top_speed_where",
    "no_load_field_weakening_top_speed_rpm",
    "reachable",
    "motor_dict",
    "max_load_nm",
    "refuse_unreachable",
]

RPM = math.pi / 30.0


def motor_dict(motor) -> dict:
    """Plain floats ``R, L_d, L_q, psi_f, J, B, pole_pairs`` of a motor (a mapping or PMSMParameters)."""
    get = (lambda k: motor[k]) if isinstance(motor, Mapping) else (lambda k: getattr(motor, k))
    out = {k: float(np.asarray(get(k))) for k in ("R", "L_d", "L_q", "psi_f", "J", "B")}
    out["pole_pairs"] = int(get("pole_pairs"))
    n = motor.get("n_phases", 3) if isinstance(motor, Mapping) else motor.n_phases
    if n != 3:  # multi-phase: the torque factor n/2 (module docstring)
        out["n_phases"] = int(n)
    return out


def steady_point(motor: Mapping, speed_rad_s: float, load_nm: float, i_d: float = 0.0) -> dict:
    """Steady state at ``speed_rad_s`` (mechanical) under ``load_nm`` with ``i_d`` (A): ``{"i_q": A,
    "current": |i_dq| A, "voltage": |u_dq| V}`` (peak phase values). ``current`` is inf when the flux
    ``psi_f + (L_d - L_q) i_d`` makes no torque."""
    p = motor["pole_pairs"]
    torque = load_nm + motor["B"] * speed_rad_s
    flux = dq.active_flux(motor["psi_f"], motor["L_d"], motor["L_q"], i_d)
    if abs(flux) < 1e-12:
        return {"i_q": math.inf, "current": math.inf, "voltage": math.inf}
    i_q = dq.q_current(dq.torque_factor(p, motor.get("n_phases", 3)), torque, flux)
    psi_d, psi_q = dq.linear_flux(motor["psi_f"], motor["L_d"], motor["L_q"], i_d, i_q)
    voltage = dq.voltage_magnitude(motor["R"], p * speed_rad_s, i_d, i_q, psi_d, psi_q)
    return {"i_q": i_q, "current": math.hypot(i_d, i_q), "voltage": voltage}


def top_speed_rpm(motor: Mapping, u_limit_v: float, load_nm: float, direction: float = 1.0) -> float:
    """Largest speed (r/min, in the sign of ``direction``) whose steady state with i_d = 0 at ``load_nm``
    needs at most ``u_limit_v``; 0 when even standstill needs more."""
    sign = 1.0 if direction >= 0 else -1.0
    need = lambda w: steady_point(motor, sign * w, load_nm)["voltage"]
    if need(0.0) > u_limit_v:
        return 0.0
    lo, hi = 0.0, 1.0
    while need(hi) <= u_limit_v and hi < 1e7:
        lo, hi = hi, 2.0 * hi
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if need(mid) <= u_limit_v else (lo, mid)
    return sign * lo / RPM


def reachable(
    motor: Mapping,
    speed_rpm: float,
    load_nm: float,
    u_limit_v: float,
    current_limit_a: float,
    field_weakening: bool = False,
) -> dict:
    """Whether the steady point (``speed_rpm``, ``load_nm``) fits the limits. Returns ``{"ok", "i_d",
    "current", "voltage", "limit"}``: ``limit`` is ``"current"`` or ``"voltage"`` when not ok, and the
    figures are those of the best i_d tried (0, or with field weakening the one needing least voltage
    within the current limit)."""
    w = speed_rpm * RPM
    candidates = [0.0]
    if field_weakening:
        candidates += [-current_limit_a * k / 200.0 for k in range(1, 201)]
    best = None
    for i_d in candidates:
        pt = steady_point(motor, w, load_nm, i_d)
        if pt["current"] > current_limit_a:
            continue
        if best is None or pt["voltage"] < best[1]["voltage"]:
            best = (i_d, pt)
    if best is None:
        pt = steady_point(motor, w, load_nm)
        return {
            "ok": False,
            "i_d": 0.0,
            "current": pt["current"],
            "voltage": pt["voltage"],
            "limit": "current",
        }
    i_d, pt = best
    ok = pt["voltage"] <= u_limit_v
    return {
        "ok": ok,
        "i_d": i_d,
        "current": pt["current"],
        "voltage": pt["voltage"],
        "limit": None if ok else "voltage",
    }


def field_weakening_top_speed_rpm(
    motor: Mapping, u_limit_v: float, current_limit_a: float, load_nm: float, direction: float = 1.0
) -> float:
    """Largest speed (r/min, sign of ``direction``) [`reachable`][pmsmjax.spec.steady_state.reachable] with
    field weakening at ``load_nm``."""
    sign = 1.0 if direction >= 0 else -1.0
    return top_speed_where(
        lambda n: reachable(motor, sign * n, load_nm, u_limit_v, current_limit_a, True)["ok"], direction
    )


def top_speed_where(ok, direction: float = 1.0, steps: int = 40) -> float:
    """Largest speed ``n`` (r/min, returned in the sign of ``direction``) with ``ok(|n|)`` True, by doubling
    from 1000 r/min and bisecting ``steps`` times; ``ok`` is assumed True below the top speed and False
    above it. 0 when ``ok(0)`` is False."""
    sign = 1.0 if direction >= 0 else -1.0
    if not ok(0.0):
        return 0.0
    lo, hi = 0.0, 1000.0
    while ok(hi) and hi < 1e6:
        lo, hi = hi, 2.0 * hi
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if ok(mid) else (lo, mid)
    return sign * lo


def no_load_field_weakening_top_speed_rpm(motor: Mapping, u_limit_v: float, current_limit_a: float) -> float:
    """No-load top speed (r/min) with field weakening in closed form, resistance neglected: at
    ``i_d = -current_limit_a`` the flux left is ``psi_f - L_d I_max``, which ``u_limit_v`` holds up to
    ``w_e = U_lim / (psi_f - L_d I_max)``; inf when the current limit cancels the magnet flux."""
    excess = motor["psi_f"] - motor["L_d"] * current_limit_a
    return math.inf if excess <= 0 else u_limit_v / (motor["pole_pairs"] * excess) * 30 / math.pi


def max_load_nm(motor: Mapping, current_limit_a: float) -> float:
    """Largest load torque (N m) i_d = 0 control holds at standstill within the current limit (torque
    factor n/2: 1.5 for three phases, from the dict's ``n_phases`` otherwise)."""
    factor = dq.torque_factor(motor["pole_pairs"], motor.get("n_phases", 3))
    return dq.active_flux_torque(factor, current_limit_a, motor["psi_f"])


def refuse_unreachable(
    motor: Mapping,
    speed_rpm: float,
    load_nm: float,
    u_dc_v: float,
    u_limit_v: float,
    current_limit_a: float,
    *,
    what: str,
    speed_flag: str = "--speed-rpm",
    load_flag: str = "--load-nm",
    u_dc_flag: str | None = None,
    current_limit_flag: str | None = None,
) -> None:
    """Raise [`ParameterError`][pmsmjax.spec.validation.ParameterError] when (``speed_rpm``, ``load_nm``) is
    not a steady point of an i_d = 0 drive within ``u_limit_v`` and ``current_limit_a`` (a comparison there
    would describe saturation); ``u_dc_flag``, ``current_limit_flag``: the knobs that raise those limits,
    named in the fix."""
    r = reachable(motor, speed_rpm, load_nm, u_limit_v, current_limit_a)
    if r["ok"]:
        return
    if r["limit"] == "current":
        raise ParameterError(
            f"{load_flag} {plain(load_nm)}: the load needs {r['current']:.1f} A, more than the "
            f"{plain(current_limit_a)} A current limit, so the drive cannot hold {plain(speed_rpm)} r/min "
            f"and {what} would describe a stalled drive: give a load of at most "
            f"{0.95 * max_load_nm(motor, current_limit_a):.1f} N m"
            + (f", or raise the current limit ({current_limit_flag})" if current_limit_flag else "")
            + "."
        )
    top = top_speed_rpm(motor, u_limit_v, load_nm, speed_rpm)
    raise ParameterError(
        f"{speed_flag} {plain(speed_rpm)}: at {plain(load_nm)} N m the drive needs {r['voltage']:.0f} V, "
        f"more than the {u_limit_v:.0f} V (peak) the inverter gives from U_dc = {plain(u_dc_v)} V, so it "
        f"would run saturated below the reference and {what} would be meaningless: with i_d = 0 the top "
        f"speed there is about {abs(top):.0f} r/min; give a speed below that"
        + (f", or raise the DC link ({u_dc_flag})" if u_dc_flag else "")
        + "."
    )
