"""The stator-frame stage of an identification: the sensor errors (and, given a winding-temperature
column, R(T) and psi_f(T) with the inverter's error voltage) fitted in the stationary frame
([`tuning.identify.sensor_errors`][tuning.identify.sensor_errors]) and taken out of the log, which the main
fit ([`tuning.identify.pipeline`][tuning.identify.pipeline]) then identifies with the fitted temperature
coefficients taken as known.
"""

import dataclasses

import numpy as np

from pmsmjax.io.log_units import merge_units
from pmsmjax.spec.validation import ParameterError
from tuning.identify.cogging_fit import check_torque_column
from tuning.identify.log import drive_log_from_columns
from tuning.identify.log_columns import counts_to_angle, read_canonical
from tuning.identify.ripple_stage import ripple_stage
from tuning.identify.sensor_errors import corrected_columns, identify_sensor_errors, sensor_log_from_columns

__all__ = ["stator_frame_stage", "fitted_temperature_coeffs"]


def stator_frame_stage(
    path, pole_pairs: int, columns: dict, units: dict, *, hold: str, u_dc, resample: bool, reference_c: float,
    dead_time: bool, encoder_lines=None, counter_bits=None, asked: bool = True, dialect=None, flux_orders=(),
    cogging_orders=(),
):  # fmt: skip
    """``(DriveLog, SensorErrors, corrected columns)``: the stator-frame fit of the log at ``path`` (sensor
    errors, and with a temperature column R(T) and psi_f(T) at ``reference_c`` degC) and the log without
    the sensor errors. ``asked``: the sensor errors were asked for (``--sensor-errors``); else the stage runs
    for the log's temperature column and its refusals say so. ``flux_orders``, ``cogging_orders``: magnet
    flux harmonics fitted with the sensor errors and cogging from the logged shaft torque, both taken out
    of the log ([`tuning.identify.ripple_stage`][tuning.identify.ripple_stage]); the errors' summary then
    has ``harmonics``."""
    try:
        return _stage(path, pole_pairs, columns, units, hold=hold, u_dc=u_dc, resample=resample,
                      reference_c=reference_c, dead_time=dead_time, encoder_lines=encoder_lines,
                      counter_bits=counter_bits, dialect=dialect, flux_orders=flux_orders,
                      cogging_orders=cogging_orders)  # fmt: skip
    except ParameterError as err:
        if asked:
            raise
        raise ParameterError(
            f"{err} (The log's temperature_c column asks for R and psi_f as functions of the winding "
            "temperature, which the stator-frame fit gives: log the phase currents, the angle and the "
            "stator-frame voltages, give known coefficients in the config's [identify] temperature_coeffs, "
            "or drop the column.)"
        ) from None


def _stage(path, pole_pairs, columns, units, *, hold, u_dc, resample, reference_c, dead_time, encoder_lines,
           counter_bits, dialect, flux_orders=(), cogging_orders=()):  # fmt: skip
    if hold == "rotor":
        raise ParameterError(
            f"log {path}: the sensor-error fit takes the logged voltage as held in the stator frame (a real "
            "inverter); a rotor-frame hold (a dq-model simulator) has no sensors to identify: drop --hold "
            "rotor or --sensor-errors."
        )
    source = f"log {path}"
    named: dict = {}
    present = read_canonical(path, columns, dialect=dialect, named_units=named)
    if cogging_orders:
        check_torque_column(present, source)
    counts_to_angle(present, pole_pairs, encoder_lines, counter_bits, source)
    units = merge_units(named, dict(units or {}), source)
    slog, cols = sensor_log_from_columns(
        present, units=units, u_dc=u_dc, resample=resample, source=source, pole_pairs=pole_pairs
    )
    narrow = _narrow_temperature(slog.temperature_c)
    if narrow:
        # R and R alpha (psi_f and psi_f beta) are one unknown each when the temperature stands still: fit
        # the machine at the logged temperature instead of a degenerate pair.
        slog = dataclasses.replace(slog, temperature_c=None)
    errors = identify_sensor_errors(
        slog, reference_c=reference_c, dead_time=dead_time, flux_orders=flux_orders
    )
    corrected = corrected_columns(cols, errors)
    if "temperature_c" in cols:
        corrected["temperature_c"] = cols["temperature_c"]
    if flux_orders or cogging_orders:
        corrected, harmonics = ripple_stage(slog, corrected, errors, pole_pairs, cogging_orders, reference_c)
        errors.summary["harmonics"] = harmonics
    log = drive_log_from_columns(corrected, pole_pairs, hold=hold, u_dc=u_dc, source=source)
    note = "currents and angle corrected by the identified sensor errors (sensor_errors)"
    notes = (*log.notes, note) + ((narrow,) if narrow else ())
    return dataclasses.replace(log, notes=notes), errors, corrected


#: A winding temperature whose 10 ms means span less than this (K) is taken as constant by the stage.
STILL_SPAN_K = 2.0


def _narrow_temperature(temperature_c) -> str | None:
    """A note when the logged temperature stands still (its 100-row means span under `STILL_SPAN_K`), else
    None."""
    if temperature_c is None:
        return None
    rows = temperature_c.size // 100 * 100
    means = temperature_c[:rows].reshape(-1, 100).mean(axis=1) if rows else temperature_c
    span = float(np.ptp(means))
    if span >= STILL_SPAN_K:
        return None
    return (
        f"the winding temperature spans {span:.2g} K (under {STILL_SPAN_K:g} K): R and psi_f are fitted at "
        "the logged temperature, without temperature coefficients"
    )


def fitted_temperature_coeffs(errors) -> dict | None:
    """The coefficients the main fit takes as known, when the stator-frame fit determined them."""
    t = errors.summary.get("temperature")
    if t is None or not (
        t["r_temp_coeff_per_k"]["identifiable"] and t["psi_f_temp_coeff_per_k"]["identifiable"]
    ):
        return None
    return {
        "reference_temperature_c": t["reference_temperature_c"],
        "r_temp_coeff_per_k": t["r_temp_coeff_per_k"]["value"],
        "psi_f_temp_coeff_per_k": t["psi_f_temp_coeff_per_k"]["value"],
    }
