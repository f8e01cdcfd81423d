"""Proportional-resonant vs dq PI current control on the book drive (accuracy figures, float64).

What it measures (every figure from one process):

1. the book scenario (1000 r/min step, 10 N m at 0.2 s) with the dq PI drive (``presets.book_drive``)
   and the PR drive (``presets.pr_drive``) and its variants (no phase lead, SOGI discretisation, no
   back-EMF feed-forward, w_c = 5 rad/s): speed rise time, dip, recovery, ITAE, peak current, and the
   fundamental alpha-beta current error over the last five electrical periods (% of |i_dq*|);
2. the steady state on a dynamometer at 1000 r/min with i_q* = 10 N m / K_t: the fundamental error, and
   for the PR variants the exact sampled-data prediction it should equal (tests/controllers/test_pr.py);
3. a current step 0 -> 5 A on the dynamometer at 1000 and 2000 r/min: 10-90 % rise, overshoot, time to
   stay within 2 % (|i_dq - i_dq*| < 0.1 A), largest |i_d| excursion: the current loop's own dynamics,
   where the phase lead and the missing dq decoupling of a stationary-frame controller show;
4. the machine.

``main(json_path)`` prints a table and writes the figures as JSON (atomically). ``quick=True`` runs
only the PI and default PR drives (for smoke tests).

    python -m benchmarks.bench_pr --json pr.json
"""

import argparse

import jax
import numpy as np

from benchmarks.bench_core import machine_info, publish
from pmsmjax import Profile, Scenario, presets, simulate
from pmsmjax.analysis.speed_step_summary import speed_step_summary
from pmsmjax.frames.three_phase import inverse_park
from pmsmjax.units import rpm_to_rad_s

__all__ = ["run", "main", "format_table"]

VARIANTS = {
    "PI (dq, decoupled, predictive)": (presets.book_drive, {}),
    "PR (default)": (presets.pr_drive, {}),
    "PR no phase lead": (presets.pr_drive, {"phase_lead": False}),
    "PR sogi": (presets.pr_drive, {"discretisation": "sogi"}),
    "PR no back-EMF ff": (presets.pr_drive, {"back_emf_feedforward": False}),
    "PR w_c = 5 rad/s": (presets.pr_drive, {"w_c": 5.0}),
}


def fundamental_error_pct(trace, t_start: float, n_periods: int) -> float:
    """Largest per-axis DFT amplitude of ``i_ab* - i_ab`` at the electrical frequency over
    ``n_periods`` whole electrical periods from ``t_start`` (s), % of the mean ``|i_dq*|``."""
    t = np.asarray(trace.t)
    theta = np.unwrap(np.asarray(trace.theta_e))
    k0 = int(np.searchsorted(t, t_start))
    per_sample = (theta[-1] - theta[k0]) / (len(t) - 1 - k0)
    k1 = k0 + int(round(2 * np.pi * n_periods / per_sample))
    e = np.asarray(inverse_park(trace.i_dq_ref, trace.theta_e) - inverse_park(trace.i_dq, trace.theta_e))
    kernel = np.exp(-1j * theta[k0:k1]) * 2 / (k1 - k0)
    amplitude = np.mean(np.hypot(*np.asarray(trace.i_dq_ref)[k0:k1].T))
    return float(100 * max(abs(e[k0:k1, 0] @ kernel), abs(e[k0:k1, 1] @ kernel)) / amplitude)


def predicted_error_pct(drive, w: float, i_dq_ref: complex) -> float | None:
    """Exact sampled-data steady-state error of a PR drive (tests/controllers/test_pr.py), % of |i_dq*|."""
    c = drive.controller.current
    if not hasattr(c, "kr"):
        return None
    m = drive.machine.motor
    R, L, psi, Ts = float(m.R), float(m.L_d), float(m.psi_f), drive.Ts
    lead = 1.5 * Ts
    z, a = np.exp(1j * w * Ts), np.exp(-R * Ts / L)
    C = float(c.kp) + float(c.kr) * np.exp(1j * w * lead if c.phase_lead else 0.0)
    emf = 1j * w * psi
    u_ff = emf * np.exp(1j * w * lead) if c.back_emf_feedforward else 0.0
    g = (1 - a) / R / z
    i_ss = (g * (C * i_dq_ref + u_ff) - emf * (z - a) / (R + 1j * w * L)) / ((z - a) + g * C)
    return float(100 * abs(i_dq_ref - i_ss) / abs(i_dq_ref))


def current_step(drive, rpm: float, step_a: float = 5.0, t_step: float = 0.03) -> dict:
    scenario = Scenario(
        duration_s=0.06,
        speed_ref=Profile.constant(rpm_to_rad_s(rpm)),
        iq_ref=Profile.step(t_step, 0.0, step_a),
    )
    tr = simulate(drive, scenario)
    k0 = int(round(t_step / drive.Ts))
    i_dq = np.asarray(tr.i_dq)[k0:]
    tt = np.asarray(tr.t)[k0:] - t_step
    iq = i_dq[:, 1]
    err = np.hypot(i_dq[:, 0], iq - step_a)
    outside = np.nonzero(err > 0.02 * step_a)[0]
    settled = len(outside) == 0 or outside[-1] + 1 < len(tt)
    return {
        "rise_ms": float((tt[np.argmax(iq >= 0.9 * step_a)] - tt[np.argmax(iq >= 0.1 * step_a)]) * 1e3),
        "overshoot_pct": float(max(iq.max() / step_a - 1.0, 0.0) * 100),
        "settle_2pct_ms": float(tt[outside[-1] + 1] * 1e3)
        if len(outside) and settled
        else (0.0 if settled else None),
        "max_abs_id_a": float(np.abs(i_dq[:, 0]).max()),
    }


def run(quick: bool = False) -> dict:
    jax.config.update("jax_enable_x64", True)
    names = list(VARIANTS)[:2] if quick else list(VARIANTS)
    book = presets.book_scenario()
    w = presets.book_motor().pole_pairs * rpm_to_rad_s(1000.0)
    iq = 10.0 / float(presets.book_motor().torque_constant)
    steady = Scenario(
        duration_s=0.15, speed_ref=Profile.constant(rpm_to_rad_s(1000.0)), iq_ref=Profile.constant(iq)
    )
    out = {}
    for name in names:
        make, options = VARIANTS[name]
        tr = simulate(make(**options), book)
        s = speed_step_summary(tr, load_time_s=0.2, current_limit_a=presets.BOOK_CURRENT_LIMIT)
        dyno = make(mode="current", mechanics="imposed", **options)
        out[name] = {
            "book": {
                k: s[k]
                for k in (
                    "rise_time_s",
                    "overshoot_pct",
                    "speed_dip_rpm",
                    "recovery_time_s",
                    "final_error_rpm",
                    "itae_rad_s",
                    "peak_phase_current_a",
                )
            }
            | {"fundamental_error_pct_last_5_periods": fundamental_error_pct(tr, 0.32, 5)},
            "steady_1000rpm_10Nm": {
                "fundamental_error_pct": fundamental_error_pct(simulate(dyno, steady), 0.09, 4),
                "predicted_pct": predicted_error_pct(dyno, w, 1j * iq),
            },
            "current_step_5A": {f"{rpm}rpm": current_step(dyno, rpm) for rpm in (1000, 2000)},
        }
    return {"dtype": "float64", "variants": out, "machine": machine_info()}


def format_table(r: dict) -> str:
    lines = [
        "book scenario (1000 r/min, 10 N m at 0.2 s) | dynamometer 1000 r/min, 10 N m | i_q step 0->5 A",
        f"{'variant':32s} {'rise ms':>7s} {'dip rpm':>7s} {'rec ms':>6s} {'ITAE':>7s} {'Ipk A':>5s} "
        f"{'fund %':>6s} | {'fund %':>6s} {'pred %':>6s} | {'rpm':>4s} {'rise ms':>7s} {'ov %':>5s} "
        f"{'2% ms':>5s} {'|id| A':>6s}",
    ]
    for name, v in r["variants"].items():
        b, s = v["book"], v["steady_1000rpm_10Nm"]
        for i, (rpm, c) in enumerate(v["current_step_5A"].items()):
            left = (
                f"{name:32s} {b['rise_time_s'] * 1e3:7.2f} {b['speed_dip_rpm']:7.1f} "
                f"{b['recovery_time_s'] * 1e3:6.1f} {b['itae_rad_s']:7.4f} {b['peak_phase_current_a']:5.2f} "
                f"{b['fundamental_error_pct_last_5_periods']:6.3f} | {s['fundamental_error_pct']:6.3f} "
                + (f"{s['predicted_pct']:6.3f}" if s["predicted_pct"] is not None else f"{'-':>6s}")
                if i == 0
                else " " * 90
            )
            settle = f"{c['settle_2pct_ms']:5.1f}" if c["settle_2pct_ms"] is not None else f"{'>30':>5s}"
            lines.append(
                f"{left} | {rpm[:-3]:>4s} {c['rise_ms']:7.2f} {c['overshoot_pct']:5.2f} {settle} "
                f"{c['max_abs_id_a']:6.3f}"
            )
    m = r["machine"]
    lines.append(f"machine: {m['cpu']}, {m['cpu_count']} cores, jax {m['jax']}")
    return "\n".join(lines)


def main(json_path: str | None = None, quick: bool = False) -> dict:
    """Run, print the table, write JSON to ``json_path`` if given; returns the figures."""
    results = run(quick=quick)
    return publish(results, format_table(results), json_path)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="proportional-resonant vs dq PI current control")
    parser.add_argument("--json", help="write the figures to this JSON file")
    parser.add_argument("--quick", action="store_true", help="PI and default PR only")
    args = parser.parse_args()
    main(args.json, args.quick)
