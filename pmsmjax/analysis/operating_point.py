"""Did a finished run reach its operating point? The share of the run at the voltage and current limits
and whether the speed reached its reference, each shortfall with its cause and remedy (the
``operating_point`` entry of ``summary.json``), judged from a [`Trace`][pmsmjax.trace.Trace].

Whether a point is reachable before any run is [`pmsmjax.spec.steady_state`][pmsmjax.spec.steady_state]'s (the
same steady-state equations, [`pmsmjax.machines.dq_equations`][pmsmjax.machines.dq_equations]).
"""

from collections.abc import Mapping

import numpy as np

from pmsmjax.machines import dq_equations as dq
from pmsmjax.spec.map_steady_state import map_reachable, map_steady_state, map_top_speed_rpm
from pmsmjax.spec.steady_state import (
    RPM,
    field_weakening_top_speed_rpm,
    motor_dict,
    reachable,
    top_speed_rpm,
)

__all__ = ["run_flags", "VOLTAGE_SATURATED", "CURRENT_LIMITED", "FIELD_WEAKENING_MARGIN"]

#: A period is at the voltage limit when the command is within 0.5 % of the limit, or when the voltage
#: the machine needs in steady state (from its measured currents and speed) is within 2 % of it.
VOLTAGE_SATURATED = (0.995, 0.98)
#: A period is at the current limit when |i_dq*| is within 0.1 % of it.
CURRENT_LIMITED = 0.999
#: Share of the voltage limit that field weakening holds (VoltageFeedbackFieldWeakening's default margin).
FIELD_WEAKENING_MARGIN = 0.95
#: Share of the run at a limit that is reported (voltage, current).
REPORTED_SHARE = (0.2, 0.5)


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
    i_d, i_q = i_dq[:, 0], i_dq[:, 1]
    on_map = map_steady_state(drive)  # a flux-map machine is judged on its map, not the linear model
    if on_map is None:
        psi_d, psi_q = dq.linear_flux(motor["psi_f"], motor["L_d"], motor["L_q"], i_d, i_q)
    else:
        psi_d, psi_q = on_map.flux(i_d, i_q)
    u_need = dq.voltage_magnitude(motor["R"], motor["pole_pairs"] * w, i_d, i_q, psi_d, psi_q, np)
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
            # settled: the last tenth of the segment within the tolerance of the tenth before it
            "settled": bool(
                abs(_window_mean(w, t, start + 0.8 * (stop - start), tail[0]) - mean_w) / RPM <= tol
            ),
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
        if on_map is None:
            r = reachable(motor, ref_rpm, seg_load, u_ok, i_lim, field_weakening)
        else:
            r = map_reachable(on_map, ref_rpm, seg_load, u_ok, field_weakening)
        where = f"the speed stayed at {got:.0f} r/min {seg['segment']}, not {ref_rpm:.0f} r/min"
        shares = (
            f"(voltage at its limit {100 * seg['voltage_limited_share']:.0f} %, current reference at its "
            f"limit {100 * seg['current_limited_share']:.0f} % of that time)"
        )
        flag = {"flag": "speed_not_reached", "segment": seg["segment"]}
        if not r["ok"] and (r["limit"] == "voltage" or field_weakening):
            if on_map is not None:
                top = map_top_speed_rpm(on_map, u_ok, seg_load, field_weakening, ref_rpm)
            elif field_weakening:
                top = field_weakening_top_speed_rpm(motor, u_ok, i_lim, seg_load, ref_rpm)
            else:
                top = top_speed_rpm(motor, u_lim, seg_load, ref_rpm)
            flag["limit"] = "voltage"
            if field_weakening:
                how = "with field weakening (any split of the current limit between i_d and i_q)"
            else:
                how = "on the MTPA locus" if on_map is not None else "with i_d = 0"
            if on_map is not None:
                how += ", on the flux map"
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
        elif seg["voltage_limited_share"] >= 0.5 and seg["settled"]:
            flag["limit"] = "voltage"
            flag["cause"] = (
                f"{where} {shares}: the speed settled there at the voltage limit although the steady point "
                f"fits the drive's limits ({r['voltage']:.0f} V of {u_ok:.0f} V, {r['current']:.1f} A of "
                f"{i_lim:g} A{' on the flux map' if on_map is not None else ''}): the control does not reach "
                "it"
                + (
                    " (the voltage-feedback field weakening moves i_d only; a machine whose voltage is "
                    "mostly its q flux needs i_q lowered as well)"
                    if field_weakening
                    else ""
                )
            )
            remedies = ["ask for at most " + f"{got:.0f} r/min" + (f" ({speed})" if speed else "")]
            u_dc_knob = names.get("u_dc")
            remedies.append("raise the DC-link voltage" + (f" ({u_dc_knob})" if u_dc_knob else ""))
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
