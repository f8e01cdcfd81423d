"""Tuned observer gains on noisy logs: the closed-loop tuning of ``pmsmjax tune --estimator`` sees no
measurement noise, so this checks what its gains do with it.

The logs and the band table of `benchmarks.observer_accuracy` (the sensored book drive with 0.5 %
white noise on voltages and currents; steps to 400, 1000, 2000 and -1000 r/min with a 10 N m load step;
each observer offline, cold start; samples after convergence pooled by true speed): angle-error RMS,
electrical degrees, per band, for the design-rule gains and for the gains of each ``gains.toml`` given.

    python -m benchmarks.observer_tuning_noise smo=tune_smo/gains.toml ekf=tune_ekf/gains.toml [--json F]
"""

import argparse
import math

import numpy as np

from benchmarks.bench_core import publish
from benchmarks.observer_accuracy import BANDS_RPM, NOISE, TARGETS_RPM, TS, _converged, _run
from pmsmjax import presets
from pmsmjax.estimators import make_observer
from pmsmjax.estimators.sensored_warmup import SensoredWarmup
from pmsmjax.recorded.synthetic_logs import drive_log, speed_scenario
from tuning.parameters import read_gains_toml, set_leaves


def tuned_observer(name: str, motor, gains: dict):
    """The design-rule observer ``name`` with ``gains`` (names ``estimator.observer.*`` of a tuned drive)."""
    holder = SensoredWarmup(make_observer(name, motor, TS), 0.02)
    names = [n.removeprefix("estimator.") for n in gains]
    dtype = np.asarray(holder.observer.model.R).dtype
    values = [np.asarray(gains[n], dtype) for n in gains]
    return set_leaves(holder, names, values).observer


def bands(obs, logs) -> dict:
    pooled = {band: [] for band in BANDS_RPM}
    for log in logs.values():
        err, _ = _run(obs, log)
        rpm = np.abs(log["omega_m"]) * 30.0 / math.pi
        keep = _converged(log)
        for lo, hi in BANDS_RPM:
            pooled[(lo, hi)].append(err[keep & (rpm >= lo) & (rpm < hi)])
    return {
        f"{lo:g}-{hi:g}": float(np.sqrt(np.mean(np.concatenate(e) ** 2))) for (lo, hi), e in pooled.items()
    }


def run(files: dict) -> dict:
    motor = presets.book_motor()
    logs = {
        rpm: drive_log(presets.book_drive(motor), speed_scenario(rpm), noise=NOISE) for rpm in TARGETS_RPM
    }
    out = {}
    for name, path in files.items():
        out[name] = {
            "design": bands(make_observer(name, motor, TS), logs),
            "tuned": bands(tuned_observer(name, motor, read_gains_toml(path)), logs),
            "gains_file": str(path),
        }
    return {"noise": NOISE, "observers": out}


def format_table(r: dict) -> str:
    lines = [
        f"Angle-error RMS, electrical degrees, on logs with {100 * r['noise']:g} % noise (design -> tuned)"
    ]
    lines.append("observer     | " + " | ".join(f"{lo:g}-{hi:g} r/min" for lo, hi in BANDS_RPM))
    for name, row in r["observers"].items():
        cells = [f"{row['design'][b]:.2f} -> {row['tuned'][b]:.2f}" for b in row["design"]]
        lines.append(f"{name:<12} | " + " | ".join(cells))
    return "\n".join(lines)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("files", nargs="+", help="NAME=gains.toml")
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    files = dict(f.split("=", 1) for f in args.files)
    results = run(files)
    publish(results, format_table(results), args.json)
