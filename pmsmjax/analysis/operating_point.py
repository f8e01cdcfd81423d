"""Is an operating point reachable, and did a run reach it? Voltage and current limits of a PMSM drive.

Steady state of the dq model (the book, ch. 1) at mechanical speed ``w`` (rad/s) under load ``T_L``
(N m) with d-axis current ``i_d`` (A)::

    T_e = T_L + B w,  i_q = T_e / (1.5 p (psi_f + (L_d - L_q) i_d)),
    u_d = R i_d - w_e L_q i_q,  u_q = R i_q + w_e (L_d i_d + psi_f),  w_e = p w,

(``1.5`` is the three-phase torque factor; a multi-phase motor's dict carries ``n_phases`` and its
``n/2`` replaces it: 3 for six phases, 2.5 for five), and the point is reachable when
``|u_dq| <= U_lim`` (the modulator's linear limit, ``U_dc / sqrt 3`` for SVPWM) and ``|i_dq| <= I_max``
(the controller's current limit). With i_d = 0 control the top speed at a load follows by bisection;
with field weakening any ``-I_max <= i_d <= 0`` may be used.

[`steady_point`][pmsmjax.analysis.operating_point.steady_point],
[`top_speed_rpm`][pmsmjax.analysis.operating_point.top_speed_rpm] and
[`reachable`][pmsmjax.analysis.operating_point.reachable] are pure Python on a dict of motor values
([`pmsmjax.io.motor_files.motor_values`][pmsmjax.io.motor_files.motor_values]), so the command line checks a
request before JAX starts. [`run_flags`][pmsmjax.analysis.operating_point.run_flags] judges a finished run
from its [`Trace`][pmsmjax.trace.Trace]: the fraction of periods at the voltage limit and at the current
limit, and whether the speed reached its reference, each shortfall with its cause and remedy (the
``operating_point`` entry of ``summary.json``).
"""

import math
from collections.abc import Mapping

import numpy as np

from pmsmjax.checks.validation import ParameterError, plain

__all__ = [
    "steady_point",
    "top_speed_rpm",
    "field_weakening_top_speed_rpm",
    "reachable",
    "motor_dict",
    "run_flags",
    "max_load_nm",
    "refuse_unreachable",
    "VOLTAGE_SATURATED",
    "CURRENT_LIMITED",
]

RPM = math.pi / 30.0
#: A period is at the voltage limit when the command is within 0.5 % of the limit, or when the voltage
#: the machine needs in steady state (from its measured currents and speed) is within 2 % of it.
VOLTAGE_SATURATED = (0.995, 0.98)
#: A period is at the current limit when |i_dq*| is within 0.1 % of it.
CURRENT_LIMITED = 0.999
#: Share of the voltage limit that field weakening holds (VoltageFeedbackFieldWeakening's default margin).
FIELD_WEAKENING_MARGIN = 0.95
#: Share of the run at a limit that is reported (voltage, current).
REPORTED_SHARE = (0.2, 0.5)


def motor_dict(motor) -> dict:
    """Plain floats ``R, L_d, L_q, psi_f, J, B, pole_pairs`` of a motor.

    Args:
        motor: A mapping or [`PMSMParameters`][pmsmjax.machines.motor.PMSMParameters].
    """
    get = (lambda k: motor[k]) if isinstance(motor, Mapping) else (lambda k: getattr(motor, k))
    out = {k: float(np.asarray(get(k))) for k in ("R", "L_d", "L_q", "psi_f", "J", "B")}
    out["pole_pairs"] = int(get("pole_pairs"))
    n = motor.get("n_phases", 3) if isinstance(motor, Mapping) else getattr(motor, "n_phases", 3)
    if n != 3:  # multi-phase: the torque factor n/2 (module docstring)
        out["n_phases"] = int(n)
    return out


def steady_point(motor: Mapping, speed_rad_s: float, load_nm: float, i_d: float = 0.0) -> dict:
    """Steady state at a speed under a load with a given d current (peak phase values).

    Args:
        motor: The motor (a mapping of [`motor_dict`][pmsmjax.analysis.operating_point.motor_dict]'s names).
        speed_rad_s: Mechanical speed, rad/s.
        load_nm: Load torque, N m.
        i_d: d current, A.

    Returns:
        ``{"i_q": A, "current": |i_dq| A, "voltage": |u_dq| V}``; ``current`` is inf when the flux
        ``psi_f + (L_d - L_q) i_d`` makes no torque.
    """
    p = motor["pole_pairs"]
    torque = load_nm + motor["B"] * speed_rad_s
    flux = motor["psi_f"] + (motor["L_d"] - motor["L_q"]) * i_d
    if abs(flux) < 1e-12:
        return {"i_q": math.inf, "current": math.inf, "voltage": math.inf}
    i_q = torque / (0.5 * motor.get("n_phases", 3) * p * flux)
    w_e = p * speed_rad_s
    u_d = motor["R"] * i_d - w_e * motor["L_q"] * i_q
    u_q = motor["R"] * i_q + w_e * (motor["L_d"] * i_d + motor["psi_f"])
    return {"i_q": i_q, "current": math.hypot(i_d, i_q), "voltage": math.hypot(u_d, u_q)}


def top_speed_rpm(motor: Mapping, u_limit_v: float, load_nm: float, direction: float = 1.0) -> float:
    """Largest speed whose steady state with i_d = 0 at ``load_nm`` needs at most ``u_limit_v``.

    Args:
        motor: The motor (a mapping of [`motor_dict`][pmsmjax.analysis.operating_point.motor_dict]'s names).
        u_limit_v: Voltage limit (peak phase), V.
        load_nm: Load torque, N m.
        direction: Sign of the speed.

    Returns:
        The speed, r/min, in the sign of ``direction``; 0 when even standstill needs more.
    """
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
    """Whether the steady point (``speed_rpm``, ``load_nm``) fits the limits.

    Args:
        motor: The motor (a mapping of [`motor_dict`][pmsmjax.analysis.operating_point.motor_dict]'s names).
        speed_rpm: Speed, r/min.
        load_nm: Load torque, N m.
        u_limit_v: Voltage limit (peak phase), V.
        current_limit_a: Current limit (peak phase), A.
        field_weakening: Allow a negative i_d to lower the voltage.

    Returns:
        ``{"ok", "i_d", "current", "voltage", "limit"}``: ``limit`` is ``"current"`` or ``"voltage"`` when
        not ok, and the figures are those of the best i_d (0, or with field weakening the one needing least
        voltage within the current limit).
    """
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
    """Largest speed [`reachable`][pmsmjax.analysis.operating_point.reachable] with field weakening at
    ``load_nm``.

    Args:
        motor: The motor (a mapping of [`motor_dict`][pmsmjax.analysis.operating_point.motor_dict]'s names).
        u_limit_v: Voltage limit (peak phase), V.
        current_limit_a: Current limit (peak phase), A.
        load_nm: Load torque, N m.
        direction: Sign of the speed.

    Returns:
        The speed, r/min, in the sign of ``direction``.
    """
    sign = 1.0 if direction >= 0 else -1.0
    ok = lambda n: reachable(motor, sign * n, load_nm, u_limit_v, current_limit_a, True)["ok"]
    if not ok(0.0):
        return 0.0
    lo, hi = 0.0, 1000.0
    while ok(hi) and hi < 1e6:
        lo, hi = hi, 2.0 * hi
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if ok(mid) else (lo, mid)
    return sign * lo


def max_load_nm(motor: Mapping, current_limit_a: float) -> float:
    """Largest load torque i_d = 0 control holds at standstill within the current limit (torque factor
    n/2: 1.5 for three phases, from the dict's ``n_phases`` otherwise).

    Args:
        motor: The motor (a mapping of [`motor_dict`][pmsmjax.analysis.operating_point.motor_dict]'s names).
        current_limit_a: Current limit (peak phase), A.

    Returns:
        The torque, N m.
    """
    return 0.5 * motor.get("n_phases", 3) * motor["pole_pairs"] * motor["psi_f"] * current_limit_a


def _window_mean(x, t, start, end):
    sel = (t >= start) & (t < end)
    return float(np.mean(x[sel])) if sel.any() else float("nan")


def run_flags(
    trace,
    drive,
    *,
    load_time_s: float | None,
    field_weakening: bool = False,
    flags: Mapping[str, str] | None = None,
    tolerance_pct: float = 2.0,
    tolerance_rpm: float = 5.0,
) -> dict:
    """How much of a finished speed-step run sat at the voltage and current limits, and whether the speed
    reached its reference.

    The speed counts as reached when its mean over the last 10 % before the load step and of the run is
    within ``tolerance_pct`` % of the reference or ``tolerance_rpm``, whichever is larger.

    Args:
        trace: The finished run.
        drive: The drive it ran.
        load_time_s: Time of the load step, s, or ``None``.
        field_weakening: Whether the drive weakens the field.
        flags: The command's names for ``speed``, ``load``, ``duration``, ``field_weakening``,
            ``current_limit`` and ``u_dc`` (``{"speed": "--speed-rpm", ...}``), used in the remedies; a
            missing one is left out.
        tolerance_pct: Speed tolerance, percent of the reference.
        tolerance_rpm: Speed tolerance, r/min.

    Returns:
        The JSON-able ``operating_point`` entry: shares, reached flags and ``flags`` (a list of
        ``{"flag", "cause", "remedy"}``; empty for a run that did what was asked).
    """
    names = dict(flags or {})
    t = np.asarray(trace.t, dtype=float)
    w = np.asarray(trace.omega_m, dtype=float)
    ref = np.asarray(trace.speed_ref, dtype=float)
    i_dq = np.asarray(trace.i_dq, dtype=float)
    i_ref = np.asarray(trace.i_dq_ref, dtype=float)
    u_cmd = np.asarray(trace.u_dq_ref, dtype=float)
    motor = motor_dict(drive.machine.motor)
    u_lim = float(np.asarray(drive.voltage_limit()))
    i_lim = float(np.asarray(drive.controller.current_limit))
    u_dc = float(np.asarray(drive.bridge.u_dc))
    p = motor["pole_pairs"]
    w_e = p * w
    u_need = np.hypot(
        motor["R"] * i_dq[:, 0] - w_e * motor["L_q"] * i_dq[:, 1],
        motor["R"] * i_dq[:, 1] + w_e * (motor["L_d"] * i_dq[:, 0] + motor["psi_f"]),
    )
    at_voltage = u_need >= VOLTAGE_SATURATED[1] * u_lim
    if drive.controller.command_kind == "voltage":
        at_voltage |= np.hypot(u_cmd[:, 0], u_cmd[:, 1]) >= VOLTAGE_SATURATED[0] * u_lim
    at_current = np.hypot(i_ref[:, 0], i_ref[:, 1]) >= CURRENT_LIMITED * i_lim

    end = float(t[-1]) + (float(t[1] - t[0]) if t.size > 1 else 0.0)
    segments = [("before the load step", 0.0, load_time_s), ("at the end", load_time_s, end)]
    if load_time_s is None:
        segments = [("at the end", 0.0, end)]
    out = {
        "voltage_limit_v": u_lim,
        "current_limit_a": i_lim,
        "voltage_limited_share": float(np.mean(at_voltage)),
        "current_limited_share": float(np.mean(at_current)),
        "speed_tolerance": f"mean speed over the last 10 % of each segment within {tolerance_pct:g} % of the "
        f"reference or {tolerance_rpm:g} r/min",
        "segments": [],
        "flags": [],
    }
    missed = []
    for label, start, stop in segments:
        tail = (start + 0.9 * (stop - start), stop)
        mean_w = _window_mean(w, t, *tail)
        mean_ref = _window_mean(ref, t, *tail)
        err_rpm = (mean_ref - mean_w) / RPM
        tol = max(tolerance_pct / 100.0 * abs(mean_ref) / RPM, tolerance_rpm)
        sel = (t >= tail[0]) & (t < tail[1])
        seg = {
            "segment": label,
            "from_s": start,
            "to_s": stop,
            "reference_rpm": mean_ref / RPM,
            "speed_rpm": mean_w / RPM,
            "reached": bool(abs(err_rpm) <= tol),
            "voltage_limited_share": float(np.mean(at_voltage[sel])) if sel.any() else 0.0,
            "current_limited_share": float(np.mean(at_current[sel])) if sel.any() else 0.0,
        }
        out["segments"].append(seg)
        if not seg["reached"]:
            missed.append(seg)

    speed, load = names.get("speed"), names.get("load")
    fw, limit_flag = names.get("field_weakening"), names.get("current_limit")
    load_nm = float(np.asarray(trace.load_torque)[-1])
    dur = names.get("duration")
    for seg in missed:
        ref_rpm, got = seg["reference_rpm"], seg["speed_rpm"]
        seg_load = load_nm if seg["segment"] == "at the end" else float(np.asarray(trace.load_torque)[0])
        # Field weakening holds a margin below the voltage limit (VoltageFeedbackFieldWeakening: 95 %).
        u_ok = FIELD_WEAKENING_MARGIN * u_lim if field_weakening else u_lim
        r = reachable(motor, ref_rpm, seg_load, u_ok, i_lim, field_weakening)
        where = f"the speed stayed at {got:.0f} r/min {seg['segment']}, not {ref_rpm:.0f} r/min"
        shares = (
            f"(voltage at its limit {100 * seg['voltage_limited_share']:.0f} %, current reference at its "
            f"limit {100 * seg['current_limited_share']:.0f} % of that time)"
        )
        flag = {"flag": "speed_not_reached", "segment": seg["segment"]}
        if not r["ok"] and (r["limit"] == "voltage" or field_weakening):
            top = (
                field_weakening_top_speed_rpm(motor, u_ok, i_lim, seg_load, ref_rpm)
                if field_weakening
                else (top_speed_rpm(motor, u_lim, seg_load, ref_rpm))
            )
            flag["limit"] = "voltage"
            how = (
                "with field weakening (any split of the current limit between i_d and i_q)"
                if field_weakening
                else ("with i_d = 0")
            )
            flag["cause"] = (
                f"{where} {shares}: holding {ref_rpm:.0f} r/min at {seg_load:g} N m needs "
                f"{r['voltage']:.0f} V {how}, more than the {u_ok:.0f} V (peak) the drive uses from U_dc = "
                f"{u_dc:.0f} V; its top speed there is about {abs(top):.0f} r/min"
            )
            remedies = [f"ask for at most {abs(top):.0f} r/min" + (f" ({speed})" if speed else "")]
            if fw and not field_weakening:
                remedies.append(f"add {fw} (MTPA and field weakening)")
            if field_weakening:
                remedies.append("raise the current limit" + (f" ({limit_flag})" if limit_flag else ""))
            u_dc_knob = names.get("u_dc")
            remedies.append("raise the DC-link voltage" + (f" ({u_dc_knob})" if u_dc_knob else ""))
        elif not r["ok"]:
            flag["limit"] = "current"
            flag["cause"] = (
                f"{where} {shares}: the load needs {r['current']:.1f} A, more than the {i_lim:g} A limit"
            )
            remedies = [
                "lower the load"
                + (f" ({load})" if load else "")
                + " or the speed"
                + (f" ({speed})" if speed else "")
            ]
            remedies.append("raise the current limit" + (f" ({limit_flag})" if limit_flag else ""))
        elif seg["current_limited_share"] >= 0.5 or seg["voltage_limited_share"] >= 0.5:
            flag["limit"] = "current" if seg["current_limited_share"] >= 0.5 else "voltage"
            flag["cause"] = (
                f"{where} {shares}: the point is within the drive's limits, but it was still getting there "
                "at the limit when the segment ended"
            )
            remedies = ["give it more time" + (f" ({dur}, or a later load step)" if dur else "")]
        else:
            flag["limit"] = None
            flag["cause"] = f"{where} {shares}: the response had not settled"
            remedies = ["give it more time" + (f" ({dur}, or a later load step)" if dur else "")]
        flag["remedy"] = "; ".join(remedies)
        out["flags"].append(flag)
    if not missed:
        if out["voltage_limited_share"] >= REPORTED_SHARE[0]:
            out["flags"].append(
                {
                    "flag": "voltage_limit",
                    "limit": "voltage",
                    "cause": f"the voltage is at its limit ({u_lim:.0f} V) for "
                    f"{100 * out['voltage_limited_share']:.0f} % of the run: the figures describe a "
                    "saturated drive",
                    "remedy": "ask for a lower speed"
                    + (f" ({speed})" if speed else "")
                    + (f" or add {fw}" if fw and not field_weakening else ""),
                }
            )
        if out["current_limited_share"] >= REPORTED_SHARE[1]:
            out["flags"].append(
                {
                    "flag": "current_limit",
                    "limit": "current",
                    "cause": f"the current reference is at the {i_lim:g} A limit for "
                    f"{100 * out['current_limited_share']:.0f} % of the run",
                    "remedy": "lower the load or the speed step"
                    + (f" ({load}, {speed})" if load and speed else "")
                    + ", or raise the current limit"
                    + (f" ({limit_flag})" if limit_flag else ""),
                }
            )
    out["ok"] = not out["flags"]
    return out


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
    """Refuse a point that is not a steady point of an i_d = 0 drive within the limits (a comparison
    there would describe saturation).

    Args:
        motor: The motor (a mapping of [`motor_dict`][pmsmjax.analysis.operating_point.motor_dict]'s names).
        speed_rpm: Speed, r/min.
        load_nm: Load torque, N m.
        u_dc_v: DC-link voltage, V.
        u_limit_v: Voltage limit (peak phase), V.
        current_limit_a: Current limit (peak phase), A.
        what: What is being run, for the message.
        speed_flag: The command's speed flag.
        load_flag: The command's load flag.
        u_dc_flag: The knob that raises the voltage limit, named in the fix.
        current_limit_flag: The knob that raises the current limit, named in the fix.

    Raises:
        ParameterError: When the point is out of reach.
    """
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
