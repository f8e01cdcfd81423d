"""Accuracy of the chapter 5 observers on logs made by the project's own drive (2 degrees RMS is the goal).

Logs: the sensored book drive (design-rule FOC, SVPWM, averaged bridge, 10 kHz) with 0.5 % white noise
on voltages and currents ([`pmsmjax.recorded.synthetic_logs`][pmsmjax.recorded.synthetic_logs]); each observer
runs offline on them with its design-rule gains and starts cold
([`pmsmjax.recorded.offline_observer.observe`][pmsmjax.recorded.offline_observer.observe]).

1. **Speed bands**: speed steps from rest to 400, 1000, 2000 and -1000 r/min with a 10 N m load step at
   0.15 s (0.3 s); the samples after convergence (20 ms after |speed| first reaches 300 r/min) pooled by
   the true |speed| into 300-600, 600-1200 and 1200-2400 r/min: angle-error RMS and max (electrical
   degrees), speed-error RMS (r/min). The book's sign switching function beside the sigmoid default, with
   the design rule's amplitude and with the smallest sound one.
2. **Half-sample bookkeeping**: the mean error of ``smo`` with and without it, noise-free, no load.
3. **Near zero**: steady 30, 100 and 200 r/min, load 0 -> 2 N m.
4. **Reversal**: +1000 -> -1000 r/min at 0.15 s, no load: where each observer loses and regains the angle.
5. **Salient machine** (L_q = 12 mH): i_d = 0 and MTPA.
6. **Design sensitivity**: the band table's worst RMS for each design-rule default moved up and down
   (what the defaults were chosen on).

    python -m benchmarks.observer_accuracy --out observer_accuracy_out

Prints the tables, writes ``accuracy.json`` and figures into ``--out``.
"""

import argparse
import dataclasses
import json
import math
from pathlib import Path

import jax
import numpy as np

from pmsmjax import presets
from pmsmjax.analysis.observer_errors import angle_error
from pmsmjax.controllers import MTPA
from pmsmjax.estimators import OBSERVERS, make_observer
from pmsmjax.io.logs import atomic_write
from pmsmjax.recorded.offline_observer import observe
from pmsmjax.recorded.synthetic_logs import drive_log, speed_scenario
from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.units import rpm_to_rad_s

TS = presets.BOOK_TS
TARGETS_RPM = (400.0, 1000.0, 2000.0, -1000.0)
BANDS_RPM = ((300.0, 600.0), (600.0, 1200.0), (1200.0, 2400.0))
NOISE = 0.005
#: Rows of the band table: (label, observer name, design-rule options).
VARIANTS = [(name, name, {}) for name in OBSERVERS] + [
    ("smo (sign)", "smo", {"switching": "sign"}),
    ("smo-pll (sign)", "smo-pll", {"switching": "sign"}),
    # The sign function with the smallest sound amplitude for these logs: 1.2 x the back-EMF at 2000 r/min.
    ("smo (sign, k 184 V)", "smo", {"switching": "sign", "k_margin": 1.2, "max_speed_rpm": 2000.0}),
]


def _run(obs, log):
    u = np.stack([log["u_alpha"], log["u_beta"]], axis=1)
    i = np.stack([log["i_alpha"], log["i_beta"]], axis=1)
    out = observe(obs, u, i, TS)
    err = np.degrees(np.asarray(angle_error(out.theta_e, log["theta_e"])))
    return err, np.asarray(out.omega_m)


def _converged(log):
    t, w = log["time"], np.abs(log["omega_m"])
    return t >= t[np.argmax(w >= rpm_to_rad_s(300.0))] + 0.02


def speed_bands(motor, logs) -> dict:
    table = {}
    for label, name, options in VARIANTS:
        obs = make_observer(name, motor, TS, **options)
        pooled = {band: ([], []) for band in BANDS_RPM}
        for log in logs.values():
            err, w_est = _run(obs, log)
            rpm = np.abs(log["omega_m"]) * 30.0 / math.pi
            keep = _converged(log)
            for lo, hi in BANDS_RPM:
                sel = keep & (rpm >= lo) & (rpm < hi)
                pooled[(lo, hi)][0].append(err[sel])
                pooled[(lo, hi)][1].append((w_est - log["omega_m"])[sel] * 30.0 / math.pi)
        row = {}
        for (lo, hi), (errs, speeds) in pooled.items():
            e, s = np.concatenate(errs), np.concatenate(speeds)
            row[f"{lo:g}-{hi:g}"] = {
                "angle_rms_deg": float(np.sqrt(np.mean(e**2))),
                "angle_max_deg": float(np.max(np.abs(e))),
                "speed_rms_rpm": float(np.sqrt(np.mean(s**2))),
                "samples": int(e.size),
            }
        table[label] = row
    return table


#: (observer, design-rule option, values tried; the default among them).
SENSITIVITY = (
    ("smo", "pole", (0.0, 0.5, 0.8)),
    ("smo", "k_margin", (1.5, 3.0)),
    ("smo", "omega_c", (1000.0, 2000.0, 4000.0)),
    ("smo", "speed_bandwidth", (200.0, 500.0, 1000.0)),
    ("smo-pll", "pll_bandwidth", (300.0, 1000.0, 2000.0)),
    ("adaptive-smo", "bandwidth", (300.0, 1000.0, 2000.0)),
    ("dq-smo", "pll_bandwidth", (500.0, 1000.0, 2000.0)),
    ("mras", "bandwidth", (300.0, 1000.0, 2000.0)),
    ("ekf", "acceleration_torque_nm", (2.0, 10.0, 50.0)),
    ("ekf", "current_noise_a", (0.02, 0.05, 0.2)),
)


def sensitivity(motor, logs) -> dict:
    """Worst band RMS (electrical deg) per option value, on the band table's logs."""
    out = {}
    for name, option, values in SENSITIVITY:
        row = {}
        for value in values:
            obs = make_observer(name, motor, TS, **{option: value})
            worst = 0.0
            per_band = {band: [] for band in BANDS_RPM}
            for log in logs.values():
                err, _ = _run(obs, log)
                rpm = np.abs(log["omega_m"]) * 30.0 / math.pi
                keep = _converged(log)
                for lo, hi in BANDS_RPM:
                    per_band[(lo, hi)].append(err[keep & (rpm >= lo) & (rpm < hi)])
            for errs in per_band.values():
                worst = max(worst, float(np.sqrt(np.mean(np.concatenate(errs) ** 2))))
            row[f"{value:g}"] = worst
        out[f"{name} {option}"] = row
    return out


def half_sample(motor) -> dict:
    out = {}
    for rpm in (1000.0, 2000.0):
        log = drive_log(presets.book_drive(motor), speed_scenario(rpm, load_nm=0.0))
        keep = log["time"] >= 0.2
        on, _ = _run(make_observer("smo", motor, TS), log)
        off, _ = _run(dataclasses.replace(make_observer("smo", motor, TS), half_sample=False), log)
        w_e = motor.pole_pairs * float(np.mean(log["omega_m"][keep]))
        out[f"{rpm:g}"] = {
            "mean_error_deg_with": float(on[keep].mean()),
            "mean_error_deg_without": float(off[keep].mean()),
            "omega_e_Ts_over_2_deg": math.degrees(w_e * TS / 2),
        }
    return out


def near_zero(motor) -> dict:
    out = {}
    for rpm in (30.0, 100.0, 200.0):
        log = drive_log(presets.book_drive(motor), speed_scenario(rpm, load_nm=2.0), noise=NOISE)
        keep = log["time"] >= 0.1
        out[f"{rpm:g}"] = {}
        for name in OBSERVERS:
            err, _ = _run(make_observer(name, motor, TS), log)
            out[f"{rpm:g}"][name] = {
                "angle_rms_deg": float(np.sqrt(np.mean(err[keep] ** 2))),
                "angle_max_deg": float(np.max(np.abs(err[keep]))),
            }
    return out


def reversal(motor):
    w = rpm_to_rad_s(1000.0)
    scenario = Scenario(0.35, Profile.step(0.15, w, -w), Profile.constant(0.0))
    log = drive_log(presets.book_drive(motor), scenario, noise=NOISE)
    t, rpm = log["time"], log["omega_m"] * 30.0 / math.pi
    out, errors = {}, {}
    for name in OBSERVERS:
        err, _ = _run(make_observer(name, motor, TS), log)
        errors[name] = err
        lost = (np.abs(err) > 30.0) & (t > 0.1)
        out[name] = {
            "lost_from_s": float(t[lost].min()) if lost.any() else None,
            "regained_at_s": float(t[lost].max()) if lost.any() else None,
            "max_abs_rpm_while_lost": float(np.max(np.abs(rpm[lost]))) if lost.any() else None,
            "angle_rms_deg_after_0.3s": float(np.sqrt(np.mean(err[t >= 0.3] ** 2))),
        }
    return out, log, errors


def salient() -> dict:
    motor = presets.book_motor(salient=True)
    out = {}
    for label, drive in (
        ("id=0", presets.book_drive(motor)),
        ("mtpa", presets.book_drive(motor, d_axis=MTPA())),
    ):
        log = drive_log(drive, speed_scenario(1000.0), noise=NOISE)
        keep = _converged(log)
        out[label] = {}
        for name in OBSERVERS:
            err, _ = _run(make_observer(name, motor, TS), log)
            out[label][name] = {
                "angle_rms_deg": float(np.sqrt(np.mean(err[keep] ** 2))),
                "angle_mean_deg": float(np.mean(err[keep])),
            }
    return out


def run() -> tuple[dict, dict]:
    motor = presets.book_motor()
    logs = {
        rpm: drive_log(presets.book_drive(motor), speed_scenario(rpm), noise=NOISE) for rpm in TARGETS_RPM
    }
    rev, rev_log, rev_errors = reversal(motor)
    results = {
        "noise": NOISE,
        "speed_bands": speed_bands(motor, logs),
        "half_sample": half_sample(motor),
        "near_zero": near_zero(motor),
        "reversal": rev,
        "salient": salient(),
        "sensitivity": sensitivity(motor, logs),
        "jax": jax.__version__,
    }
    log = logs[1000.0]
    figures = {
        "errors_1000": (log, {n: _run(make_observer(n, motor, TS), log)[0] for n in OBSERVERS}),
        "sign_1000": (
            log,
            {
                "smo (sign)": _run(make_observer("smo", motor, TS, switching="sign"), log)[0],
                "smo (sigmoid)": _run(make_observer("smo", motor, TS), log)[0],
            },
        ),
        "reversal": (rev_log, rev_errors),
    }
    return results, figures


def format_tables(r: dict) -> str:
    lines = [f"angle error after convergence, electrical deg RMS (max), {r['noise'] * 100:g} % noise"]
    bands = list(next(iter(r["speed_bands"].values())))
    lines.append(f"{'observer':20s}" + "".join(f"{b + ' r/min':>22s}" for b in bands))
    for label, row in r["speed_bands"].items():
        cells = "".join(f"{row[b]['angle_rms_deg']:>13.3f} ({row[b]['angle_max_deg']:6.2f})" for b in bands)
        lines.append(f"{label:20s}{cells}")
    lines.append("half-sample bookkeeping (smo, no noise, no load): mean angle error, deg")
    for rpm, h in r["half_sample"].items():
        lines.append(
            f"  {rpm:>5s} r/min: with {h['mean_error_deg_with']:+.3f}, "
            f"without {h['mean_error_deg_without']:+.3f} (omega_e Ts/2 = {h['omega_e_Ts_over_2_deg']:.3f})"
        )
    lines.append("near zero (steady, 2 N m), angle error RMS deg after 0.1 s")
    for rpm, row in r["near_zero"].items():
        lines.append(
            f"  {rpm:>4s} r/min: " + ", ".join(f"{n} {v['angle_rms_deg']:.2f}" for n, v in row.items())
        )
    lines.append(
        "reversal +1000 -> -1000 r/min at 0.15 s: angle error > 30 deg between (s), |speed| max there"
    )
    for name, v in r["reversal"].items():
        if v["lost_from_s"] is None:
            lines.append(f"  {name:13s} never lost; RMS after 0.3 s {v['angle_rms_deg_after_0.3s']:.2f}")
        else:
            lines.append(
                f"  {name:13s} {v['lost_from_s']:.4f} - {v['regained_at_s']:.4f}, up to "
                f"{v['max_abs_rpm_while_lost']:.0f} r/min; "
                f"RMS after 0.3 s {v['angle_rms_deg_after_0.3s']:.2f}"
            )
    lines.append("salient machine (L_q = 12 mH), 1000 r/min, angle error RMS (mean) deg")
    for label, row in r["salient"].items():
        cells = ", ".join(
            f"{n} {v['angle_rms_deg']:.2f} ({v['angle_mean_deg']:+.2f})" for n, v in row.items()
        )
        lines.append(f"  {label}: {cells}")
    lines.append("design sensitivity: worst band RMS (deg) per value (defaults in the band table above)")
    for key, row in r["sensitivity"].items():
        lines.append(f"  {key:32s} " + ", ".join(f"{v}: {e:.3f}" for v, e in row.items()))
    return "\n".join(lines)


def save_figures(figures: dict, out: Path) -> list[Path]:
    from pmsmjax.plotting.observers import angle_error_figure
    from pmsmjax.plotting.traces import save_figure

    written = []
    titles = {
        "errors_1000": ("Angle error, 1000 r/min step and 10 N m load step, 0.5 % noise", 5.0),
        "sign_1000": ("Sign vs sigmoid switching function at 10 kHz, 1000 r/min", 90.0),
        "reversal": ("Speed reversal +1000 -> -1000 r/min", 90.0),
    }
    for key, (log, errors) in figures.items():
        title, ylim = titles[key]
        fig = angle_error_figure(log["time"], errors, log["omega_m"] * 30.0 / math.pi, title, ylim)
        written.append(save_figure(fig, out / f"{key}.png"))
    return written


def main(out: str = "observer_accuracy_out") -> dict:
    results, figures = run()
    print(format_tables(results))
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    atomic_write(folder / "accuracy.json", lambda f: f.write(json.dumps(results, indent=2).encode()))
    written = save_figures(figures, folder)
    print(f"wrote {folder / 'accuracy.json'}, " + ", ".join(str(p) for p in written))
    return results


if __name__ == "__main__":
    jax.config.update("jax_enable_x64", True)
    parser = argparse.ArgumentParser(description="accuracy of the chapter 5 observers on noisy drive logs")
    parser.add_argument("--out", default="observer_accuracy_out", help="output folder (created)")
    main(parser.parse_args().out)
