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
- R's relative error; the inverter error voltage's relative error; wall times (log making, fit);
- whether ``motor.toml`` would be written: the map passes the drive file's check (its MTPA locus rising
  with the current up to the grid's corner current on both torque signs), for every log here.

The reluctance machine (tuning/identify/reluctance_reference_log.py:
a PM-assisted SyRM, the power-law current map of Hinkkanen et al. 2017 with strong cross-saturation, the
q-axis incremental inductance falling 57 to 6 mH), fitted at the default settings with R given:

- its 35-point staircase (400 r/min one way, 40 ms a point, noise 0.05 A and 0.5 V): the RMS flux error over
  the visited currents, over those within 0.5 A of an operating point ("dwells") and over the rest (the
  transients' paths), against the same figures for the steady-state estimate at the operating points
  (``u = R i + w_e J psi`` averaged over each dwell's second half, interpolated the same way);
- a log of its ordinary operation (speed loop from rest through both directions, load steps, i_d a fixed
  share of |i_q|): the RMS flux error over the visited currents.

The power-law model's fit (``--flux-model power-law``,
[`tuning.identify.flux_model_fit`][tuning.identify.flux_model_fit]) on the same logs, with the paper's
exponents and with S, T, U fitted: the RMS flux error over the visited currents against the grid's, and
the coefficients' errors and whether their 95 % intervals cover the truth. On the reluctance machine the
model is the one the log was made with (a self-consistency check of the fit, not an independent test); the
saturated IPM's map is not of the model's form.
"""

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.bench_core import machine_info, publish
from pmsmjax.io.drive_files import drive_spec
from pmsmjax.io.flux_map_files import write_flux_map_csv
from pmsmjax.machines.flux_map import FluxMapGrid
from pmsmjax.spec.validation import ParameterError
from tuning.identify.flux_map_files import write_flux_map_motor
from tuning.identify.flux_map_fit import fit_flux_map
from tuning.identify.flux_model_fit import fit_power_law_flux_map
from tuning.identify.log import drive_log_from_columns
from tuning.identify.reluctance_reference_log import (
    STAIRCASE_D,
    STAIRCASE_Q,
    SYRM,
    steady_state_map,
    syrm_flux,
    syrm_speed_controlled_log,
    syrm_staircase_log,
)
from tuning.identify.saturated_reference_log import SATURATED_IPM, flux_map_log, saturated_flux

OPS_D, OPS_Q = np.array([-12.0, -8.0, -4.0, 0.0, 4.0]), np.arange(-12.0, 12.5, 4.0)


def _rms(grid, points):
    err = np.array([grid.at(*p)[0] for p in points]) - saturated_flux(SATURATED_IPM, *points.T)[0]
    return float(np.sqrt(np.mean(err**2)))


def _drive_file_accepts(fit, pole_pairs: int) -> bool:
    """Whether ``motor.toml`` of ``fit`` passes the drive file's checks (as ``identify --flux-map`` writes it
    only then)."""
    with tempfile.TemporaryDirectory() as folder:
        write_flux_map_csv(Path(folder) / "flux_map.csv", fit.grid, measured=fit.measured)
        path = write_flux_map_motor(Path(folder) / "motor.toml", fit, pole_pairs, {"J": 0.01, "B": 0.001})
        try:
            drive_spec(str(path))
        except ParameterError:
            return False
    return True


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
            "motor_toml": _drive_file_accepts(fit, p),
            "log_s": t1 - t0,
            "fit_s": t2 - t1,
        }
    return out


def _syrm_errors(grid, i_dq) -> list[float]:
    """RMS flux error shares of the flux range: all visited 0.25 A cells, those near a dwell, the rest."""
    points = np.unique(np.round(i_dq / 0.25).astype(int), axis=0) * 0.25
    true = syrm_flux(SYRM, *points.T)[0]
    err = np.sum((grid.flux(points)[0] - true) ** 2, axis=1) / 2.0
    D, Q = np.meshgrid(STAIRCASE_D, STAIRCASE_Q, indexing="ij")
    dwells = np.stack([D.ravel(), Q.ravel()], -1)
    near = np.min(np.linalg.norm(points[:, None] - dwells[None], axis=-1), axis=1) < 0.5
    flux_range = float(np.ptp(true, axis=0).max())
    return [float(np.sqrt(np.mean(e))) / flux_range for e in (err, err[near], err[~near])]


def run_reluctance() -> dict:
    """The reluctance machine's staircase and ordinary operation (module docstring)."""
    p = SYRM["pole_pairs"]
    t0 = time.perf_counter()
    log = drive_log_from_columns(syrm_staircase_log(seed=1), p, hold="stator")
    t1 = time.perf_counter()
    fit = fit_flux_map(log, p, R=SYRM["R"])
    t2 = time.perf_counter()
    out = {
        "staircase": {
            "grid_step_a": float(fit.grid.step[0]),
            "flux_rms_share": _syrm_errors(fit.grid, log.i_dq),
            "steady_state_rms_share": _syrm_errors(steady_state_map(log, SYRM["R"], p), log.i_dq),
            "energy_constraints": fit.constraints,
            "motor_toml": _drive_file_accepts(fit, p),
            "log_s": t1 - t0,
            "fit_s": t2 - t1,
        }
    }
    speed = [(0.0, 600.0), (0.3, 250.0), (0.5, -600.0), (0.8, -300.0)]
    load = [(0.15, 6.0), (0.25, -4.0), (0.4, 8.0), (0.62, -6.0), (0.72, 4.0), (0.9, -8.0)]
    raw = syrm_speed_controlled_log(
        SYRM, speed, load, duration_s=1.0, inertia_kgm2=0.015, friction_nms=0.005, seed=2
    )
    log = drive_log_from_columns(raw, p, hold="stator")
    t3 = time.perf_counter()
    fit = fit_flux_map(log, p, R=SYRM["R"])
    out["ordinary"] = {
        "grid_step_a": float(fit.grid.step[0]),
        "flux_rms_share": _syrm_errors(fit.grid, log.i_dq)[0],
        "energy_constraints": fit.constraints,
        "measured_points": int(fit.measured.sum()),
        "grid_points": int(fit.measured.size),
        "motor_toml": _drive_file_accepts(fit, p),
        "fit_s": time.perf_counter() - t3,
    }
    return out


#: The reluctance machine's coefficients in the model's names (its truth).
SYRM_TRUTH = {"a_x0": SYRM["a_d0"], "a_xx": SYRM["a_dd"], "a_y0": SYRM["a_q0"], "a_yy": SYRM["a_qq"],
              "a_xy": SYRM["a_dq"], "psi_f": SYRM["psi_pm"]}  # fmt: skip


def _power_law_rows(log, pole_pairs, errors, truth=None, **options) -> dict:
    """The power-law model's fit of ``log`` with the paper's and with fitted exponents: flux errors
    (``errors(grid)``, share of the flux range) of the model and of its start, the grid fit; and, with a
    ``truth``, each coefficient's relative error and whether its interval covers it."""
    out = {}
    for exponents in ("paper", "fitted"):
        t0 = time.perf_counter()
        fit = fit_power_law_flux_map(log, pole_pairs, exponents=exponents, **options)
        row = {
            "flux_rms_share": errors(fit.map.grid),
            "grid_flux_rms_share": errors(fit.grid_fit.grid),
            "magnet": fit.magnet,
            "residual_rms_wb": fit.residual_rms_wb,
            "grid_residual_rms_wb": fit.grid_fit.residual_rms_wb,
            "motor_toml": _drive_file_accepts(fit.map, pole_pairs),
            "fit_s": time.perf_counter() - t0,
            "parameters": fit.parameters,
        }
        if truth is not None:
            row["coefficients"] = {
                name: {
                    "error": fit.parameters[name]["value"] / value - 1.0,
                    "covered": fit.parameters[name]["ci95"][0] <= value <= fit.parameters[name]["ci95"][1],
                }
                for name, value in truth.items()
                if name in fit.parameters
            }
        out[exponents] = row
    return out


def run_power_law() -> dict:
    """The power-law model's fit on the reluctance machine's staircase and ordinary operation and on the
    saturated IPM's walk (module docstring)."""
    p = SYRM["pole_pairs"]
    out = {}
    stair = drive_log_from_columns(syrm_staircase_log(seed=1), p, hold="stator")
    out["reluctance_staircase"] = _power_law_rows(
        stair, p, lambda g: _syrm_errors(g, stair.i_dq)[0], SYRM_TRUTH, R=SYRM["R"]
    )
    speed = [(0.0, 600.0), (0.3, 250.0), (0.5, -600.0), (0.8, -300.0)]
    load = [(0.15, 6.0), (0.25, -4.0), (0.4, 8.0), (0.62, -6.0), (0.72, 4.0), (0.9, -8.0)]
    raw = syrm_speed_controlled_log(
        SYRM, speed, load, duration_s=1.0, inertia_kgm2=0.015, friction_nms=0.005, seed=2
    )
    ordinary = drive_log_from_columns(raw, p, hold="stator")
    out["reluctance_ordinary"] = _power_law_rows(
        ordinary, p, lambda g: _syrm_errors(g, ordinary.i_dq)[0], SYRM_TRUTH, R=SYRM["R"]
    )
    q = SATURATED_IPM["pole_pairs"]
    raw = flux_map_log(SATURATED_IPM, OPS_D, OPS_Q, speed_rpm=1000.0, dwell_s=4e-3, seed=1)
    walk = drive_log_from_columns(raw, q, hold="stator")
    points = np.unique(np.round(walk.i_dq / 0.25).astype(int), axis=0) * 0.25
    flux_range = float(np.ptp(saturated_flux(SATURATED_IPM, *points.T)[0], axis=0).max())
    out["ipm_walk"] = _power_law_rows(walk, q, lambda g: _rms(g, points) / flux_range, step_a=2.0)
    return out


def format_power_law(r: dict) -> str:
    lines = ["power-law model fit: RMS flux error / range over the visited currents (the grid fit's beside)"]
    lines.append("log                    exponents  model      grid       magnet  motor.toml  fit s")
    for log in ("reluctance_staircase", "reluctance_ordinary", "ipm_walk"):
        for exponents in ("paper", "fitted"):
            x = r[log][exponents]
            model, grid = 100 * x["flux_rms_share"], 100 * x["grid_flux_rms_share"]
            lines.append(
                f"{log:22s} {exponents:9s} {model:7.3f} %  {grid:7.3f} %"
                f"  {x['magnet']:6s}  {'written' if x['motor_toml'] else 'refused':10s}  {x['fit_s']:.1f}"
            )
            for name, c in x.get("coefficients", {}).items():
                e = x["parameters"][name]
                lines.append(
                    f"    {name:6s} {e['value']:.5g} [{e['ci95'][0]:.5g}, {e['ci95'][1]:.5g}] "
                    f"error {100 * c['error']:+.2f} %{'' if c['covered'] else '  NOT COVERED'}"
                )
    return "\n".join(lines)


def format_table(r: dict) -> str:
    lines = ["log             flux rms / range   steady-point map   R error   V_e error   fit s   motor.toml"]
    for name in ("plain", "inverter_error"):
        x = r[name]
        ve = "-" if x["inverter_error_rel"] is None else f"{100 * x['inverter_error_rel']:+.2f} %"
        lines.append(
            f"{name:15s} {100 * x['flux_rms_share']:8.3f} %         "
            f"{100 * x['steady_point_map_rms_share']:8.3f} %       {100 * x['R_error']:+.2f} %   "
            f"{ve:9s}   {x['fit_s']:.2f}   {'written' if x['motor_toml'] else 'refused'}"
        )
    s, o = r["reluctance"]["staircase"], r["reluctance"]["ordinary"]
    lines.append(
        f"reluctance machine staircase, default grid ({s['grid_step_a']:g} A), fit {s['fit_s']:.1f} s, "
        f"motor.toml {'written' if s['motor_toml'] else 'refused'}, RMS flux error / range:"
    )
    lines.append("                 all visited   at dwells   on transient paths")
    for name, key in (("identified", "flux_rms_share"), ("steady-state", "steady_state_rms_share")):
        a, b, c = (100 * v for v in s[key])
        lines.append(f"  {name:14s} {a:8.3f} %   {b:7.3f} %   {c:10.3f} %")
    lines.append(
        f"  ordinary operation ({o['grid_step_a']:g} A grid, {o['measured_points']} of {o['grid_points']} "
        f"points measured): {100 * o['flux_rms_share']:.3f} %, fit {o['fit_s']:.1f} s, "
        f"motor.toml {'written' if o['motor_toml'] else 'refused'}"
    )
    return "\n".join(lines)


def main(json_path: str | None = None) -> dict:
    results = run()
    results["reluctance"] = run_reluctance()
    results["power_law"] = run_power_law()
    table = format_table(results) + "\n" + format_power_law(results["power_law"])
    return publish(results, table, json_path)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", default=None, help="write the results to this JSON file")
    main(parser.parse_args().json)
