"""Identify motor parameters (R, L_d, L_q, psi_f, J, B) with error bars from a logged drive run.

Pipeline (each step in its own module):

1. [`tuning.identify.log`][tuning.identify.log]: read CSV/.mat/.npz, map columns and units, turn every frame
   into dq, check everything (gaps, units, consistency) before any fitting.
2. [`tuning.identify.electrical`][tuning.identify.electrical]: current residuals over multiple-shooting
   windows (R, L_d, L_q, psi_f and a dead-time voltage), the voltage held as the recording held it (``hold``,
   as in [`pmsmjax.recorded.replay`][pmsmjax.recorded.replay]); given the measured speed they do not involve
   the mechanics.
3. [`tuning.identify.mechanical`][tuning.identify.mechanical]: speed residuals at window ends (J, B, a
   constant load, and the electrical parameters through the torque).
   [`tuning.identify.fit`][tuning.identify.fit]: equation-error warm starts, then one output-error
   Levenberg-Marquardt solve (optimistix, JAX forward-mode Jacobians) over both groups.
4. [`tuning.identify.uncertainty`][tuning.identify.uncertainty]: standard errors, 95 % intervals (in log space
   for positive parameters, so they stay positive; Student t with each variance estimate's effective degrees
   of freedom, reported as ``ci95_dof``), identifiability, the weak directions and what excitation would
   fix them.

[`identify`][tuning.identify.pipeline.identify] works on a [`DriveLog`][tuning.identify.log.DriveLog];
[`identify_file`][tuning.identify.pipeline.identify_file] reads a file and writes ``DIR/params.json`` and
``DIR/fit.png``. Everything runs in float64.
"""

import dataclasses
import json
import math
import os
import time
from collections.abc import Mapping

import jax
import numpy as np
from scipy import stats

from pmsmjax.io.log_formats import READER_KEYS, reader_options
from pmsmjax.io.logs import atomic_write, check_output_folder
from pmsmjax.recorded.replay import DEFAULT_HOLD
from pmsmjax.spec.validation import ParameterError
from tuning.identify import electrical as el
from tuning.identify import fit as id_fit
from tuning.identify import mechanical as me
from tuning.identify.fit import FitResult
from tuning.identify.log import DriveLog, load_drive_log, read_log_config
from tuning.identify.stator_stage import fitted_temperature_coeffs, stator_frame_stage
from tuning.identify.temperature_scaling import check_coeffs
from tuning.identify.thermal_network_fit import temperature_report
from tuning.identify.uncertainty import (
    ADVICE,
    EXCITATION_AVERAGE_S,
    MIN_EXCITATION,
    excitation,
    motion_excitation,
    weak_directions,
)

__all__ = ["IdentifyOptions", "identify", "identify_file", "NAMES", "UNITS"]

#: The motor parameters every result reports.
NAMES = ("R", "L_d", "L_q", "psi_f", "J", "B")
UNITS = {
    "R": "ohm",
    "L_d": "H",
    "L_q": "H",
    "psi_f": "Wb",
    "J": "kg m^2",
    "B": "N m s/rad",
    "T_c": "N m",
    "V_dt": "V",
}
#: A fitted model must explain at least this share of the integrated voltages (else: mislabelled).
MIN_EXPLAINED = 0.9


@dataclasses.dataclass(frozen=True)
class IdentifyOptions:
    """Settings of an identification.

    - `pole_pairs`: number of pole pairs (known, not identified).
    - `fixed`: ``{name: value}`` (SI) of parameters held fixed, any of R, L_d, L_q, psi_f, J, B, T_c,
      V_dt; the others are estimated.
    - `start`: ``{name: value}`` start values replacing the warm start.
    - `load`: ``"constant"`` (estimate a constant load torque T_c besides a logged T_L) or ``"none"``.
    - `dead_time`: estimate an inverter voltage error ``V_dt`` (V per phase, sign of the phase current),
      smoothed over `dead_time_eps_a` A.
    - `electrical_window_s`, `mechanical_window_s`: shooting-window lengths, s.
    - `n_substeps`: RK4 steps per log interval (1 is accurate at 10 kHz; see the tests).
    - `rel_tol`: a parameter is identifiable when its relative standard error is below this.
    - `max_steps`: Levenberg-Marquardt step limit per solve.
    - `temperature_coeffs`: None, or known temperature coefficients ``{"reference_temperature_c": T_ref,
      "r_temp_coeff_per_k": alpha, "psi_f_temp_coeff_per_k": beta}`` for a log with a ``temperature_c``
      column: R and psi_f are fitted at T_ref
      ([`tuning.identify.temperature_scaling`][tuning.identify.temperature_scaling]).
    """

    pole_pairs: int
    fixed: Mapping[str, float] = dataclasses.field(default_factory=dict)
    start: Mapping[str, float] = dataclasses.field(default_factory=dict)
    load: str = "constant"
    dead_time: bool = False
    dead_time_eps_a: float = 0.05
    electrical_window_s: float = 0.1
    mechanical_window_s: float = 0.01
    n_substeps: int = 1
    rel_tol: float = 0.05
    max_steps: int = 100
    temperature_coeffs: Mapping[str, float] | None = None

    def __post_init__(self):
        object.__setattr__(self, "temperature_coeffs", check_coeffs(self.temperature_coeffs))
        if not isinstance(self.pole_pairs, int) or isinstance(self.pole_pairs, bool) or self.pole_pairs < 1:
            raise ParameterError(
                f"pole_pairs must be a positive integer (poles / 2), got {self.pole_pairs!r}."
            )
        known = set(NAMES) | {"T_c", "V_dt"}
        for what, d in (("fixed", self.fixed), ("start", self.start)):
            bad = sorted(set(d) - known)
            if bad:
                raise ParameterError(f"{what}: unknown parameter(s) {bad}; use {', '.join(sorted(known))}.")
            for k, v in d.items():
                if not isinstance(v, (int, float)) or not math.isfinite(v):
                    raise ParameterError(f"{what}[{k!r}] must be a finite number in SI units, got {v!r}.")
                if k not in ("T_c", "V_dt") and v <= 0:
                    raise ParameterError(f"{what}[{k!r}] must be > 0 ({UNITS[k]}), got {v}.")
        if self.load not in ("constant", "none"):
            raise ParameterError(f"load must be 'constant' or 'none', got {self.load!r}.")
        for name in ("electrical_window_s", "mechanical_window_s", "rel_tol", "dead_time_eps_a"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and v > 0 and math.isfinite(v)):
                raise ParameterError(f"{name} must be a positive number, got {v!r}.")
        for name in ("n_substeps", "max_steps"):
            v = getattr(self, name)
            if not isinstance(v, int) or v < 1:
                raise ParameterError(f"{name} must be a positive int, got {v!r}.")


@dataclasses.dataclass
class IdentifyResult:
    """`summary`: the JSON-able result (``params.json``); `fit`: the fit; `log`: the checked log."""

    summary: dict
    fit: FitResult
    log: DriveLog


def identify(log: DriveLog, options: IdentifyOptions) -> IdentifyResult:
    """Identify the motor of ``log``; see the module docstring. Raises ParameterError for bad input."""
    with jax.enable_x64(True):
        return _identify(log, options)


def _identify(log: DriveLog, opt: IdentifyOptions) -> IdentifyResult:
    t_start = time.perf_counter()
    dt = float(np.median(np.diff(log.time)))
    w_el = max(2, round(opt.electrical_window_s / dt))
    w_me = max(2, round(opt.mechanical_window_s / dt))
    if log.captures == 1 and log.n - 1 < w_el:
        raise ParameterError(
            f"{log.source}: {log.n} samples ({log.time[-1] - log.time[0]:.3g} s) is shorter than one "
            f"electrical window ({opt.electrical_window_s} s): record longer or shorten the window."
        )
    fixed = dict(opt.fixed)
    if opt.load == "none":
        fixed.setdefault("T_c", 0.0)
    if opt.temperature_coeffs is not None and log.temperature_c is None:
        raise ParameterError(
            f"{log.source}: temperature_coeffs are given but the log has no temperature_c column (winding "
            "temperature, degC): map it (--columns temperature_c=NAME) or drop temperature_coeffs."
        )
    el_fixed = {k: v for k, v in fixed.items() if k in el.ELECTRICAL_NAMES}
    _, explained = el.warm_start(
        log, opt.pole_pairs, log.hold, el_fixed, opt.dead_time, temperature_coeffs=opt.temperature_coeffs
    )
    _check_consistency(log, opt, explained)
    t_checked = time.perf_counter()
    motion = motion_excitation(log.omega_m, opt.load, log.segments)
    held = tuple(n for n, m in motion.items() if not m["excited"] and n not in fixed)
    try:
        result = _fit(log, opt, fixed, w_el, w_me, held)
    except np.linalg.LinAlgError as err:
        raise ParameterError(
            f"{log.source}: the fit failed numerically ({err}): the model does not describe this log as read "
            f"(voltage hold {log.hold!r}; --hold auto picks the one that fits), or the log does not excite "
            "the parameters (hold some fixed with --fix)."
        ) from None
    t_end = time.perf_counter()
    summary = _summary(log, opt, result, {n: motion[n] for n in held})
    summary["wall_time_s"] = time.perf_counter() - t_start
    summary["timing_s"] = {"checks": t_checked - t_start, "fit": t_end - t_checked}
    return IdentifyResult(summary, result, log)


def _fit(log: DriveLog, opt: IdentifyOptions, fixed: dict, w_el: int, w_me: int, held=()) -> FitResult:
    return id_fit.fit(
        log,
        opt.pole_pairs,
        hold=log.hold,
        fixed=fixed,
        start=dict(opt.start),
        dead_time=opt.dead_time,
        dead_time_eps=opt.dead_time_eps_a,
        windows=(w_el, w_me),
        n_substeps=opt.n_substeps,
        max_steps=opt.max_steps,
        held=held,
        temperature_coeffs=opt.temperature_coeffs,
    )


def _check_consistency(log: DriveLog, opt: IdentifyOptions, explained: float) -> None:
    """Refuse logs the model cannot describe (before the output-error fit)."""
    if explained < MIN_EXPLAINED:
        raise ParameterError(
            f"{log.source}: the PMSM voltage equations explain only {100 * explained:.1f} % of the logged "
            "voltages (a consistent log gives > 99 %): columns are probably mislabelled or in the wrong "
            "frame (u_d/u_q or i_d/i_q swapped, a sign flipped, stator-frame signals labelled dq, "
            "phase voltages not phase-to-neutral) or pole_pairs is wrong."
        )
    if any("theta_e integrated" in n for n in log.notes):
        # No angle to check the speed unit against: compare L_q seen through the speed and through di/dt.
        ratio, rel = el.coupling_ratio(log, opt.pole_pairs)
        if np.isfinite(rel) and rel < 0.1 and abs(np.log(abs(ratio))) > 0.3:
            hint = (
                "omega_m looks like r/min: set units omega_m = 'rpm'"
                if abs(np.log(ratio / (np.pi / 30.0))) < 0.2
                else "check the unit of omega_m (mechanical rad/s) and pole_pairs"
            )
            raise ParameterError(
                f"{log.source}: the speed term of the voltage equations is {ratio:.3g} x what the current "
                f"dynamics imply (1 x expected): {hint}."
            )


def _entries(
    fit: FitResult, rel_tol: float, torque_rms: float, excited: dict | None = None, held: dict | None = None
) -> dict:
    out = {}
    se_theta = np.sqrt(np.diag(fit.cov))
    se_white = np.sqrt(np.diag(fit.cov_white))
    dval = fit.pmap.value_jacobian(fit.theta)
    for k, name in enumerate(fit.pmap.free_names):
        v = fit.values[name]
        positive = fit.pmap.positive[fit.pmap.names.index(name)]
        s = float(se_theta[k])
        finite = math.isfinite(s)
        dof = float(fit.dof[k])
        # Student t with the variance estimate's effective degrees of freedom (1.96 as dof -> inf).
        t95 = float(stats.t.ppf(0.975, dof)) if math.isfinite(dof) else float(stats.norm.ppf(0.975))
        if positive:
            stderr = v * s if finite else None
            ci = [v * math.exp(-t95 * s), v * math.exp(t95 * s)] if finite else [None, None]
            ok = finite and s < rel_tol
        else:
            stderr = float(dval[k]) * s if finite else None
            ci = [v - t95 * stderr, v + t95 * stderr] if finite else [None, None]
            ref = torque_rms if name == "T_c" else max(abs(v), 1.0)
            ok = finite and stderr < rel_tol * ref
        entry = {
            "value": v,
            "stderr": stderr,
            "ci95": ci,
            "ci95_dof": dof if math.isfinite(dof) else None,
            "identifiable": bool(ok),
            "stderr_white_noise": (v if positive else float(dval[k])) * float(se_white[k])
            if math.isfinite(se_white[k])
            else None,
            "unit": UNITS[name],
            "fixed": False,
        }
        quiet = (excited or {}).get(name)
        if quiet is not None and not quiet["excited"]:
            ok = entry["identifiable"] = False
        if not ok:
            # A linearised interval around a value the data does not pin down is not a 95 % interval.
            entry["ci95"] = [None, None]
            entry["note"] = (
                "not determined by this log: the value is where the fit stopped and the local stderr "
                "understates the uncertainty; see identifiability.advice"
            )
            if quiet is not None and not quiet["excited"]:
                entry["note"] = (
                    f"not determined by this log: {quiet['current']} varies by "
                    f"{quiet['variation_rms_a']:.3g} A RMS ({1e3 * EXCITATION_AVERAGE_S:g} ms average) "
                    f"against {quiet['noise_a']:.3g} A of noise ({quiet['ratio']:.2g}x, {MIN_EXCITATION:g}x "
                    "needed): what moves it is noise, so the fitted value and its stderr say nothing about "
                    "the motor; see identifiability.advice"
                )
        out[name] = entry
    for name in fit.pmap.names:
        if name in (held or {}):
            out[name] = {"value": fit.values[name], "stderr": None, "ci95": [None, None], "ci95_dof": None,
                         "identifiable": False, "unit": UNITS[name], "fixed": False,
                         "note": f"not determined by this log: {held[name]['reason']}; held at its warm "
                         "start (not fitted); see identifiability.advice"}  # fmt: skip
        elif name not in out:
            v = fit.values[name]
            out[name] = {"value": v, "stderr": 0.0, "ci95": [v, v], "identifiable": None, "unit": UNITS[name],
                         "fixed": True}  # fmt: skip
    return out


def _weak(fit: FitResult, rel_tol: float) -> list[dict]:
    """Weak directions among the positive (log-parameterised, so relative) parameters; the signed ones
    (load, dead-time voltage) have no common scale and are judged one by one in their entries."""
    names = fit.pmap.free_names
    keep = [j for j, n in enumerate(names) if fit.pmap.positive[fit.pmap.names.index(n)]]
    return weak_directions(fit.cov[np.ix_(keep, keep)], [names[j] for j in keep], rel_tol)


def _summary(log: DriveLog, opt: IdentifyOptions, fit: FitResult, held: dict) -> dict:
    d, md = fit.electrical, fit.mechanical
    err_i, err_w = fit.residuals["i_dq"], fit.residuals["omega_end"]
    torque = np.asarray(me.electromagnetic_torque(fit.values, log.i_dq, opt.pole_pairs))
    excited = excitation(log.time, log.i_dq, bounds=log.segments)
    params = _entries(fit, opt.rel_tol, float(np.sqrt(np.mean(torque**2))), excited, held)
    rms = lambda x, axis=None: np.sqrt(np.mean(np.square(x), axis=axis))
    unidentifiable = [n for n, p in params.items() if p["identifiable"] is False]
    lam = np.linalg.eigvalsh(fit.M)
    temperature = _temperature(log, opt, params)
    return {
        **temperature,
        "parameters": {n: params[n] for n in NAMES},
        "extra_parameters": {n: p for n, p in params.items() if n not in NAMES},
        "identifiability": {
            "relative_tolerance": opt.rel_tol,
            "not_identifiable": unidentifiable,
            "weak_directions": _weak(fit, opt.rel_tol),
            "advice": {n: ADVICE[n] for n in unidentifiable},
            "condition_number": float(np.sqrt(lam.max() / lam.min())) if lam.min() > 0 else None,
            "excitation": {
                "rule": f"an inductance is identifiable only when its current axis varies by at least "
                f"{MIN_EXCITATION:g}x its noise level (RMS after a {1e3 * EXCITATION_AVERAGE_S:g} ms average "
                "against the noise from first differences)",
                **excited,
            },
        },
        "residual_rms": {
            "i_d_A": float(rms(err_i[..., 0])),
            "i_q_A": float(rms(err_i[..., 1])),
            "omega_m_window_end_rad_s": float(rms(err_w)),
        },
        "residual_rms_per_window": {
            "electrical_window_s": float(np.sum(np.asarray(d.dt[0]))),
            "i_d_A": rms(err_i[..., 0], axis=1).tolist(),
            "i_q_A": rms(err_i[..., 1], axis=1).tolist(),
            "mechanical_window_s": float(np.sum(np.asarray(md.dt[0]))),
            "omega_m_rad_s": np.abs(err_w).tolist(),
        },
        "noise_estimate": {
            "i_d_A": fit.sigma["i_d"],
            "i_q_A": fit.sigma["i_q"],
            "omega_m_window_end_rad_s": fit.sigma["omega_end"],
            "variance_factor": fit.s2,
        },
        "solver": {
            "method": "output-error Levenberg-Marquardt (optimistix), multiple shooting, JAX Jacobians",
            "steps": fit.steps,
            "converged": fit.ok,
            "electrical_windows": int(d.dt.shape[0]),
            "mechanical_windows": int(md.dt.shape[0]),
            "covariance": "Gauss-Newton sandwich with Newey-West lags "
            f"{fit.lags['electrical']} samples (electrical), {fit.lags['mechanical']} windows (mechanical); "
            "95 % intervals: Student t with each parameter's effective degrees of freedom (ci95_dof)",
        },
        "log": {
            "source": log.source,
            "samples": int(log.n),
            "captures": log.captures,
            "duration_s": float(log.time[-1] - log.time[0]),
            "hold": log.hold,
            "pole_pairs": opt.pole_pairs,
            "notes": list(log.notes),
        },
    }


def _temperature(log: DriveLog, opt: IdentifyOptions, params: dict) -> dict:
    """``{"temperature": ...}`` when R and psi_f were fitted at a reference temperature (their entries get
    ``at_temperature_c``), else ``{}``."""
    coeffs = opt.temperature_coeffs
    if coeffs is None or log.temperature_c is None:
        return {}
    for name in ("R", "psi_f"):
        params[name]["at_temperature_c"] = coeffs["reference_temperature_c"]
    return {
        "temperature": {
            **coeffs,
            "coefficients": "given, not fitted",
            "logged_temperature_c": [float(np.min(log.temperature_c)), float(np.max(log.temperature_c))],
            "model": "R (1 + r_temp_coeff_per_k (T_w - T_ref)), "
            "psi_f (1 + psi_f_temp_coeff_per_k (T_w - T_ref)), "
            "T_w the mean logged winding temperature of each shooting window",
        }
    }


def identify_file(
    log_path: str | os.PathLike,
    out_dir: str | os.PathLike,
    pole_pairs: int,
    *,
    config: str | os.PathLike | None = None,
    columns: dict | None = None,
    units: dict | None = None,
    hold: str | None = None,
    u_dc: float | None = None,
    resample: bool = False,
    figures: bool = True,
    sensor_errors: bool = False,
    reference_c: float = 20.0,
    ambient_c: float | None = None,
    encoder_lines: int | None = None,
    counter_bits: int | None = None,
    flux_orders=(),
    cogging_orders=(),
    two_mass: bool = False,
    **options,
) -> IdentifyResult:
    """Read ``log_path``, identify, write ``out_dir/params.json`` (and ``fit.png``); returns the result.

    `hold`: ``"auto"`` (default,
    [`pmsmjax.recorded.replay.DEFAULT_HOLD`][pmsmjax.recorded.replay.DEFAULT_HOLD]: the hold that fits better,
    [`tuning.identify.hold`][tuning.identify.hold]), ``"stator"`` or ``"rotor"``. `config`: TOML with
    ``[columns]``, ``[units]``, ``[log]`` (``hold``, ``u_dc``, ``resample``, ``encoder_lines``,
    ``counter_bits``; how the file is written: ``format``, ``delimiter``, ``header_row``, ``decimal``,
    [`pmsmjax.io.log_formats`][pmsmjax.io.log_formats]) and ``[identify]``
    ([`IdentifyOptions`][tuning.identify.pipeline.IdentifyOptions] fields; ``fixed``/``start`` as tables);
    explicit arguments win over it. `sensor_errors`: first fit the current sensors' offsets, their gains
    relative to sensor a and the encoder offset from the phase currents and the measured angle
    ([`tuning.identify.sensor_errors`][tuning.identify.sensor_errors]), take them out of the log and
    identify the motor on the corrected log; the summary gets a ``sensor_errors`` entry. A log with a
    ``temperature_c`` column (winding temperature, degC) is fitted that way whether or not `sensor_errors`
    is asked for: the stator-frame fit also gives R and psi_f at `reference_c` (degC) and their temperature
    coefficients, the main fit takes those coefficients as known, and the thermal network is fitted
    ([`tuning.identify.thermal_network_fit`][tuning.identify.thermal_network_fit]; `ambient_c`, degC, when
    known, else fitted); the summary gets a ``temperature`` entry. `encoder_lines`, `counter_bits`: the
    encoder of an ``encoder_counts`` column
    ([`tuning.identify.log_columns.angle_from_counts`][tuning.identify.log_columns.angle_from_counts]).
    `flux_orders`, `cogging_orders`: magnet flux harmonics (fitted in the stator-frame stage, which they
    turn on) and cogging torque (from a logged shaft torque ``T_L``) of those orders per electrical
    revolution, taken out of the log before the main fit
    ([`tuning.identify.ripple_stage`][tuning.identify.ripple_stage]); the summary gets ``harmonics``.
    `two_mass`: fit a compliant shaft (motor and load inertia, stiffness, damping) to the motor speed of a
    run with speed steps, driven by the identified machine's torque
    ([`tuning.identify.two_mass_fit`][tuning.identify.two_mass_fit]; turns the stator-frame stage on); the
    summary gets ``two_mass``.
    Everything is checked before anything is compiled; files are written atomically.
    """
    cfg = read_log_config(config) if config else {"columns": {}, "units": {}, "log": {}, "identify": {}}
    cols = {**cfg["columns"], **(columns or {})}
    unit_map = {**cfg["units"], **(units or {})}
    log_cfg = cfg["log"]
    allowed = {"hold", "u_dc", "resample", "encoder_lines", "counter_bits", "ambient_c", *READER_KEYS}
    bad = sorted(set(log_cfg) - allowed)
    if bad:
        raise ParameterError(f"[log] table: unknown keys {bad}; allowed: {', '.join(sorted(allowed))}.")
    dialect, cols, unit_map = reader_options(log_cfg, cols, unit_map)
    ambient_c = ambient_c if ambient_c is not None else log_cfg.get("ambient_c")
    fields = {f.name for f in dataclasses.fields(IdentifyOptions)}
    bad = sorted(set(cfg["identify"]) - fields)
    if bad:
        raise ParameterError(f"[identify] table: unknown keys {bad}; allowed: {', '.join(sorted(fields))}.")
    opts = IdentifyOptions(pole_pairs=pole_pairs, **{**cfg["identify"], **options})
    read = {
        "hold": hold or log_cfg.get("hold", DEFAULT_HOLD),
        "u_dc": u_dc if u_dc is not None else log_cfg.get("u_dc"),
        "resample": resample or bool(log_cfg.get("resample", False)),
        "encoder_lines": encoder_lines if encoder_lines is not None else log_cfg.get("encoder_lines"),
        "counter_bits": counter_bits if counter_bits is not None else log_cfg.get("counter_bits"),
        "dialect": dialect,
    }
    ripple = {"flux_orders": tuple(flux_orders), "cogging_orders": tuple(cogging_orders)}
    sensors, asked = None, sensor_errors or bool(flux_orders or cogging_orders or two_mass)
    sensor_errors = asked
    if not sensor_errors:
        log = load_drive_log(log_path, pole_pairs, columns=cols, units=unit_map, **read)
        sensor_errors = log.temperature_c is not None and opts.temperature_coeffs is None
    if sensor_errors:
        log, sensors, corrected = stator_frame_stage(
            log_path, pole_pairs, cols, unit_map, **read, reference_c=reference_c, dead_time=opts.dead_time,
            asked=asked, **ripple,
        )  # fmt: skip
        shaft = None
        if two_mass:
            from tuning.identify.two_mass_fit import two_mass_from_columns

            shaft = two_mass_from_columns(corrected, sensors.machine, sensors.summary.get("harmonics"),
                                          pole_pairs, reference_c, log.segments, log.source)  # fmt: skip
        coeffs = fitted_temperature_coeffs(sensors)
        if coeffs is not None and opts.temperature_coeffs is None:
            opts = dataclasses.replace(opts, temperature_coeffs=coeffs)
    out = check_output_folder(out_dir)
    result = identify(log, opts)
    if sensors is not None:
        harmonics = sensors.summary.pop("harmonics", None)
        result.summary["sensor_errors"] = sensors.summary
        if harmonics:
            result.summary["harmonics"] = harmonics
        if shaft is not None:
            result.summary["two_mass"] = shaft
        if "temperature" in sensors.summary:
            result.summary["temperature"] = temperature_report(sensors, corrected, log.segments, ambient_c)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write(out / "params.json", lambda f: f.write(json.dumps(result.summary, indent=2).encode()))
    if figures:
        from tuning.identify.plots import save_fit_figure

        save_fit_figure(result, out / "fit.png")
    return result
