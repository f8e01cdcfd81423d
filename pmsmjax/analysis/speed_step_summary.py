"""The figures of merit a drive engineer reads off a speed-step-and-load-step run."""

import numpy as np

from pmsmjax.analysis import metrics
from pmsmjax.trace import Trace
from pmsmjax.units import rad_s_to_rpm, rpm_to_rad_s


def speed_step_summary(
    trace: Trace,
    *,
    load_time_s: float | None,
    current_limit_a: float,
    settle_band: float = 0.02,
    recovery_band_rpm: float = 10.0,
) -> dict:
    """Metrics of a run whose speed reference steps at t = 0 and whose load steps at ``load_time_s``.

    Step metrics (rise, overshoot, settling, steady-state error) are taken on ``[0, load_time_s)``; the
    load response (dip, recovery to within ``recovery_band_rpm``) after it. ITAE is of the speed error in
    rad/s over the whole run (rad s).

    Args:
        trace: The run.
        load_time_s: Time of the load step, s, or ``None`` (no load response).
        current_limit_a: The drive's phase-current limit, A.
        settle_band: Settling band, fraction of the step.
        recovery_band_rpm: Recovery band of the load response, r/min.

    Returns:
        The figures by name: speeds in r/min, times in s, currents in A (``rise_time_s``,
        ``overshoot_pct``, ``settling_time_s``, ``steady_state_error_rpm``, ``itae_rad_s``,
        ``peak_phase_current_a``, ``current_limit_respected``, with a load step ``speed_dip_rpm`` and
        ``recovery_time_s``, and more).
    """
    t = np.asarray(trace.t)
    w = np.asarray(trace.omega_m)
    ref = np.asarray(trace.speed_ref)
    w_start, w_final = float(w[0]), float(ref[0])
    n_step = len(t) if load_time_s is None else int(np.searchsorted(t, load_time_s))
    window = max(1, n_step // 10)
    ts, ws = t[:n_step], w[:n_step]
    out = {
        "final_speed_rpm": float(rad_s_to_rpm(w[-1])),
        "reference_speed_rpm": float(rad_s_to_rpm(w_final)),
        "rise_time_s": float(metrics.rise_time(ts, ws, w_start, w_final)),
        "overshoot_pct": float(metrics.overshoot(ws, w_start, w_final)),
        "settling_time_s": float(metrics.settling_time(ts, ws, w_start, w_final, settle_band)),
        "steady_state_error_rpm": float(rad_s_to_rpm(metrics.steady_state_error(ws, ref[:n_step], window))),
        "final_error_rpm": float(rad_s_to_rpm(metrics.steady_state_error(w, ref, window))),
        "itae_rad_s": float(metrics.itae(t, metrics.tracking_error(ref, w))),
        "peak_phase_current_a": float(metrics.peak_phase_current(np.asarray(trace.i_abc))),
        "rms_phase_current_a": float(metrics.rms_phase_current(np.asarray(trace.i_abc))),
        "current_limit_a": float(current_limit_a),
    }
    out["current_limit_respected"] = bool(out["peak_phase_current_a"] <= current_limit_a * 1.001)
    if load_time_s is not None:
        band = rpm_to_rad_s(recovery_band_rpm)
        dip, recovery = metrics.disturbance_dip(t, w, load_time_s, float(ref[n_step - 1]), band)
        out["load_time_s"] = float(load_time_s)
        out["speed_dip_rpm"] = float(rad_s_to_rpm(dip))
        out["recovery_time_s"] = float(recovery)
        out["recovery_band_rpm"] = float(recovery_band_rpm)
    return {k: (None if isinstance(v, float) and not np.isfinite(v) else v) for k, v in out.items()}
