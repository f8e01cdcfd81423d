"""Flux-map identification benchmark (``python -m benchmarks.flux_map_identification [--json PATH]``).

The log ([`tuning.identify.saturated_reference_log`][tuning.identify.saturated_reference_log]): the saturated
IPM of ``presets/motors/saturated_ipm_map.csv`` (analytic co-energy model, SciPy DOP853) at +-1000 r/min under
a NumPy current loop walking the operating points i_d in {-12, -8, -4, 0, 4} A x i_q in {-12 .. 12} A
(step 4 A, 4 ms each), noise 0.05 A and 0.5 V; a second log adds a bridge's voltage error (1 us dead time
at 10 kHz and 311 V plus a 0.8 V drop: 3.91 V per phase, its sign ramping over the PWM ripple, not the
fit's tanh model; the fit finds the sign's width itself). Figures:

- RMS flux error of the identified map (2 A grid) over the visited currents (each 0.25 A raster cell the
  log reached counted once), as a share of the flux range there, against the same figure for the true map
  sampled at the 35 steady operating points and interpolated by the same Hermite interpolant;
- R's relative error; the inverter error voltage's relative error; wall times (log making, fit).
"""

import argparse
import time

import numpy as np

from benchmarks.bench_core import machine_info, publish
from pmsmjax.machines.flux_map import FluxMapGrid
from tuning.identify.flux_map_fit import fit_flux_map
from tuning.identify.log import drive_log_from_columns
from tuning.identify.saturated_reference_log import SATURATED_IPM, flux_map_log, saturated_flux

OPS_D, OPS_Q = np.array([-12.0, -8.0, -4.0, 0.0, 4.0]), np.arange(-12.0, 12.5, 4.0)


def _rms(grid, points):
    err = np.array([grid.at(*p)[0] for p in points]) - saturated_flux(SATURATED_IPM, *points.T)[0]
    return float(np.sqrt(np.mean(err**2)))


def run(dead_time_s: float = 1e-6, device_drop_v: float = 0.8) -> dict:
    p = SATURATED_IPM["pole_pairs"]
    out = {"machine": machine_info()}
    u_err = dead_time_s / 1e-4 * 311.0 + device_drop_v  # the log maker's default period and DC voltage
    for name, on in (("plain", 0.0), ("inverter_error", 1.0)):
        err = on * u_err
        t0 = time.perf_counter()
        raw = flux_map_log(
            SATURATED_IPM,
            OPS_D,
            OPS_Q,
            speed_rpm=1000.0,
            dwell_s=4e-3,
            dead_time_s=on * dead_time_s,
            device_drop_v=on * device_drop_v,
            seed=1,
        )
        log = drive_log_from_columns(raw, p, hold="stator")
        t1 = time.perf_counter()
        fit = fit_flux_map(log, p, step_a=2.0, inverter_error=err > 0)
        t2 = time.perf_counter()
        points = np.unique(np.round(log.i_dq / 0.25).astype(int), axis=0) * 0.25
        flux_range = float(np.ptp(saturated_flux(SATURATED_IPM, *points.T)[0], axis=0).max())
        D, Q = np.meshgrid(OPS_D, OPS_Q, indexing="ij")
        steady = saturated_flux(SATURATED_IPM, D, Q)[0]
        steady_map = FluxMapGrid(OPS_D, OPS_Q, steady[..., 0], steady[..., 1])
        out[name] = {
            "samples": int(log.n),
            "flux_rms_share": _rms(fit.grid, points) / flux_range,
            "steady_point_map_rms_share": _rms(steady_map, points) / flux_range,
            "R_error": fit.R / SATURATED_IPM["R"] - 1.0,
            "inverter_error_v": fit.V_e,
            "inverter_error_rel": None if fit.V_e is None else fit.V_e / err - 1.0,
            "error_smoothing_a": fit.error_smoothing_a,
            "measured_points": int(fit.measured.sum()),
            "grid_points": int(fit.measured.size),
            "log_s": t1 - t0,
            "fit_s": t2 - t1,
        }
    return out


def format_table(r: dict) -> str:
    lines = ["log             flux rms / range   steady-point map   R error   V_e error   fit s"]
    for name in ("plain", "inverter_error"):
        x = r[name]
        ve = "-" if x["inverter_error_rel"] is None else f"{100 * x['inverter_error_rel']:+.2f} %"
        lines.append(
            f"{name:15s} {100 * x['flux_rms_share']:8.3f} %         "
            f"{100 * x['steady_point_map_rms_share']:8.3f} %       {100 * x['R_error']:+.2f} %   "
            f"{ve:9s}   {x['fit_s']:.2f}"
        )
    return "\n".join(lines)


def main(json_path: str | None = None) -> dict:
    results = run()
    return publish(results, format_table(results), json_path)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", default=None, help="write the results to this JSON file")
    main(parser.parse_args().json)
