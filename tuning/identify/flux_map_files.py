"""The files of ``pmsmjax identify --flux-map``: read the log, fit
([`tuning.identify.flux_map_fit`][tuning.identify.flux_map_fit]), write ``DIR/flux_map.csv`` (the map with its
``measured`` marks, [`pmsmjax.io.flux_map_files`][pmsmjax.io.flux_map_files]), ``DIR/flux_map.json`` (R, the
inverter voltage error and its sign width, the residual, the marks' count; with ``--flux-model power-law``
the fitted model's parameters and intervals) and ``DIR/motor.toml``, a drive
file whose ``[motor] flux_map`` is the identified map ([`pmsmjax.io.drive_files`][pmsmjax.io.drive_files]).

A constant-speed walk does not determine J and B: ``motor.toml`` takes them from ``--fix J=... B=...`` or
the prior drive (``--motor PRIOR``, which also gives ``[ratings]`` and ``[inverter]``); without either it
is not written and [`flux_map_motor_missing`][tuning.identify.flux_map_files.flux_map_motor_missing] names
what is missing.
"""

import dataclasses
import json
from pathlib import Path

import numpy as np

from pmsmjax.io.drive_files import write_drive_file
from pmsmjax.io.flux_map_files import MA_CURRENT_A, write_flux_map_csv
from pmsmjax.io.logs import atomic_write, check_output_folder
from pmsmjax.spec.plausibility import MAX_RESISTANCE_OHM
from pmsmjax.spec.validation import ParameterError, plain
from tuning.identify.flux_map_fit import FluxMapFit, fit_flux_map
from tuning.identify.flux_model_fit import FluxModelFit, fit_power_law_flux_map
from tuning.identify.log import load_drive_log
from tuning.identify.motor_file import prior_stated_tables

__all__ = ["identify_flux_map_file", "flux_map_motor_missing", "write_flux_map_motor"]

#: Flux per ampere (H) below which a log whose currents exceed MA_CURRENT_A is taken to be in mA: a real
#: kA machine links volt-seconds of flux (1e-3 H and more), a motor logged in mA 1e-5 H.
APPARENT_INDUCTANCE_FLOOR_H = 1e-4
#: What the flux-map fit cannot give and a drive file needs.
MECHANICAL = ("J", "B")


def identify_flux_map_file(
    log_path,
    out_dir,
    pole_pairs: int,
    *,
    fixed: dict,
    inverter_error: bool,
    step_a=None,
    q_symmetric: bool = True,
    flux_model: str = "grid",
    exponents: str = "paper",
    **log_options,
) -> FluxMapFit:
    """Read ``log_path`` (``log_options``: columns, units, hold, u_dc, resample as
    [`tuning.identify.log.load_drive_log`][tuning.identify.log.load_drive_log]), fit, write ``flux_map.csv``
    and ``flux_map.json`` to ``out_dir``. `fixed`: ``{"R": ohm}`` or empty; `q_symmetric`: the map symmetric
    about the d axis ([`fit_flux_map`][tuning.identify.flux_map_fit.fit_flux_map]); `flux_model`:
    ``"grid"`` or ``"power-law"`` (the map sampled from the fitted power-law model,
    [`fit_power_law_flux_map`][tuning.identify.flux_model_fit.fit_power_law_flux_map], with `exponents`
    ``"paper"`` or ``"fitted"``; ``flux_map.json`` then holds its parameters under ``"flux_model"``).
    Returns the written map's fit."""
    log = load_drive_log(log_path, pole_pairs, **log_options)
    out = check_output_folder(out_dir)
    check_units(log, pole_pairs, fixed)
    model = None
    if flux_model == "power-law":
        model = fit_power_law_flux_map(
            log,
            pole_pairs,
            step_a=step_a,
            R=fixed.get("R"),
            inverter_error=inverter_error,
            exponents=exponents,
        )
        fit = model.map
    else:
        fit = fit_flux_map(
            log,
            pole_pairs,
            step_a=step_a,
            R=fixed.get("R"),
            inverter_error=inverter_error,
            q_symmetric=q_symmetric,
        )
    out.mkdir(parents=True, exist_ok=True)
    how = "" if model is None else " --flux-model power-law (the fitted model sampled on the grid)"
    header = (
        f"Identified by pmsmjax identify --flux-map{how} from {log.source}: A, Wb "
        "(peak, amplitude-invariant dq).\n"
        "measured = 0: the log did not reach the point; its value continues its neighbours, do not trust it."
    )
    write_flux_map_csv(out / "flux_map.csv", fit.grid, header=header, measured=fit.measured)
    summary = {
        "log": log.source,
        "R_ohm": fit.R,
        "R_fixed": fit.R_fixed,
        "inverter_error_v": fit.V_e,
        "inverter_error_sign_width_a": fit.error_smoothing_a,
        "grid_i_d_a": [float(fit.grid.i_d[0]), float(fit.grid.i_d[-1]), int(fit.grid.i_d.size)],
        "grid_i_q_a": [float(fit.grid.i_q[0]), float(fit.grid.i_q[-1]), int(fit.grid.i_q.size)],
        "measured_points": int(fit.measured.sum()),
        "grid_points": int(fit.measured.size),
        "residual_rms_wb": fit.residual_rms_wb,
        "energy_constraints": fit.constraints,
        "q_symmetric": fit.q_symmetric,
        "windows": fit.n_windows,
        "notes": list(log.notes),
    }
    if model is not None:
        summary["flux_model"] = flux_model_summary(model)
    atomic_write(out / "flux_map.json", lambda f: f.write(json.dumps(summary, indent=2).encode()))
    return fit


def flux_model_summary(model: FluxModelFit) -> dict:
    """``flux_map.json``'s ``"flux_model"``: the power-law model's parameters with their 95 % intervals, its
    form and the gridded fit's residual beside its own."""
    return {
        "model": "power-law saturation model, Hinkkanen et al., IEEE Trans. Ind. Appl. 53(3), 2017, "
        "doi:10.1109/TIA.2016.2644624",
        "axes": "x = psi_q (high-permeance axis), y = psi_d - psi_f (flux-barrier axis); "
        "i_q = (a_x0 + a_xx |x|^S + a_xy/(V+2) |x|^U |y|^(V+2)) x, "
        "i_d = (a_y0 + a_yy |y|^T + a_xy/(U+2) |x|^(U+2) |y|^V) y - i_f",
        "magnet": model.magnet,
        "exponents": model.exponents,
        "parameters": model.parameters,
        "values": dataclasses.asdict(model.model),
        "residual_rms_wb": model.residual_rms_wb,
        "grid_fit_residual_rms_wb": model.grid_fit.residual_rms_wb,
        "newton_residual_a": model.newton_residual_a,
        "steps": model.steps,
    }


def check_units(log, pole_pairs: int, fixed: dict) -> None:
    """Refuse, before fitting and before any file is written, a log whose currents are in mA (they reach
    `MA_CURRENT_A` while the flux the voltages imply per ampere is below
    `APPARENT_INDUCTANCE_FLOOR_H`) and a ``--fix R`` in mohm."""
    R = fixed.get("R")
    if R is not None and R > MAX_RESISTANCE_OHM:
        raise ParameterError(
            f"--fix R={plain(R)} ohm is not a drive's stator resistance (at most {plain(MAX_RESISTANCE_OHM)} "
            f"ohm): it looks like mohm: give R={plain(R * 1e-3)} (ohm)."
        )
    current = float(np.abs(log.i_dq).max())
    omega_e = float(np.abs(pole_pairs * log.omega_m).max())
    if current > MA_CURRENT_A and omega_e > 0:
        flux = float(np.hypot(*log.u_dq.T).max()) / omega_e  # Wb, the flux the voltages imply at speed
        if flux / current < APPARENT_INDUCTANCE_FLOOR_H:
            raise ParameterError(
                f"{log.source}: currents reach {plain(current)} A while the voltages imply about "
                f"{flux:.3g} Wb of flux: it looks like the currents are in mA: give --units i_d=mA i_q=mA "
                "or write them in A."
            )


def flux_map_motor_missing(fixed: dict, prior) -> list[str]:
    """The mechanical values (J, B) neither ``fixed`` nor the ``prior`` drive gives."""
    return [n for n in MECHANICAL if n not in fixed and prior is None]


def write_flux_map_motor(path, fit: FluxMapFit, pole_pairs: int, fixed: dict, prior=None) -> Path:
    """Write the drive file of the identified map (module docstring) to ``path``; ``flux_map.csv`` is
    expected beside it."""
    motor = {"flux_map": "flux_map.csv", "R": fit.R, "pole_pairs": pole_pairs}
    comments = {"motor.R": "held fixed (--fix), not identified" if fit.R_fixed else "identified with the map"}
    for name in MECHANICAL:
        if name in fixed:
            motor[name] = fixed[name]
            comments[f"motor.{name}"] = "given (--fix)"
        else:
            motor[name] = prior.motor[name]
            comments[f"motor.{name}"] = (
                f"not determined by a constant-speed log: the prior's ({prior.source})"
            )
    tables = {"motor": motor}
    if prior is not None:
        tables |= prior_stated_tables(prior)
    header = "Identified by pmsmjax identify --flux-map (tuning.identify): the flux map and R; SI units."
    write_drive_file(path, tables, header=header, comments=comments)
    return Path(path)
