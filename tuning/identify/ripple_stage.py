"""The ripple step of an identification's stator-frame stage (``--flux-harmonics``, ``--cogging-orders``):
the flux harmonics the stator-frame fit found
([`tuning.identify.flux_harmonics_fit`][tuning.identify.flux_harmonics_fit]) and the cogging torque from
the logged shaft torque ([`tuning.identify.cogging_fit`][tuning.identify.cogging_fit]) are reported and
taken out of the log, so that the main fit ([`tuning.identify.pipeline`][tuning.identify.pipeline]), whose
machine is sinusoidal, sees the machine without them:

- the voltages become the alpha-beta voltages less the harmonics' back-EMF, exactly in volt-seconds over
  each interval: ``u_k - (psi_h,ab(theta_{k+1}) - psi_h,ab(theta_k)) / dt_k`` (the voltage is held over the
  interval, so the main fit reads the same integral);
- the load torque ``T_L`` (when logged) loses the harmonics' torque and the cogging torque, which the main
  fit's ``J dw/dt = T_e - B w - T_L`` does not model.
"""

import math

import numpy as np

from tuning.identify.cogging_fit import electromagnetic_torque, fit_cogging
from tuning.identify.flux_harmonics_fit import flux_ab

__all__ = ["ripple_stage", "harmonics_table"]

_VOLTAGES = ("u_alpha", "u_beta", "u_a", "u_b", "u_c", "d_a", "d_b", "d_c", "U_dc")


def ripple_stage(slog, corrected: dict, errors, pole_pairs: int, cogging_orders, reference_c: float):
    """``(columns, harmonics)``: the corrected columns without the ripple (module docstring) and the
    ``harmonics`` entry of ``params.json`` (``flux`` and ``cogging``, each when asked for).

    Args:
        slog: The [`SensorLog`][tuning.identify.sensor_errors.SensorLog] (its held alpha-beta voltages, V).
        corrected: The columns with the sensor errors taken out
            ([`corrected_columns`][tuning.identify.sensor_errors.corrected_columns]), SI.
        errors: The stator-frame fit ([`SensorErrors`][tuning.identify.sensor_errors.SensorErrors]).
        pole_pairs: Pole pairs.
        cogging_orders: Cogging orders per electrical revolution (``()``: none).
        reference_c: The temperature of the machine's psi_f, degC.
    """
    out = dict(corrected)
    harmonics = {}
    th = corrected["theta_e"]
    if "flux_harmonics" in errors.machine:
        harmonics["flux"] = errors.summary.pop("flux_harmonics")
        orders, coeffs = errors.machine["flux_harmonics"]
        psi = flux_ab(th, orders, coeffs)
        u = slog.u_ab[:, 0] + 1j * slog.u_ab[:, 1]
        dt = np.diff(corrected["time"])
        u = u - np.concatenate([np.diff(psi) / dt, [0.0]])
        for name in _VOLTAGES:
            out.pop(name, None)
        out["u_alpha"], out["u_beta"] = u.real, u.imag
    if cogging_orders:
        cog = fit_cogging(out, errors.machine, pole_pairs, cogging_orders, slog.segments, reference_c,
                          slog.source)  # fmt: skip
        harmonics["cogging"] = cog
    if "T_L" in out:
        full = electromagnetic_torque(out, errors.machine, pole_pairs, reference_c)
        sinusoidal = electromagnetic_torque(
            out, {k: v for k, v in errors.machine.items() if k != "flux_harmonics"}, pole_pairs, reference_c
        )
        ripple = full - sinusoidal
        for row in harmonics.get("cogging", {}).get("rows", []):
            n, c, phi = row["order"], row["amplitude"]["value"], row["phase_rad"]["value"]
            ripple = ripple + c * np.sin(n * th + phi)
        out["T_L"] = corrected["T_L"] - ripple
    return out, harmonics


def harmonics_table(harmonics: dict) -> tuple[dict, list[str]]:
    """``([harmonics] table, notes)``: the identified rows ``[order, amplitude, phase]`` of ``params.json``'s
    ``harmonics`` (flux in Wb, cogging in N m, phases in rad); a row the log does not determine is left out
    and named in the notes."""
    table, notes = {}, []
    for key in ("flux", "cogging"):
        rows = []
        for row in harmonics.get(key, {}).get("rows", []):
            if row["amplitude"]["identifiable"]:
                phase = math.remainder(row["phase_rad"]["value"], 2.0 * math.pi)
                rows.append([row["order"], row["amplitude"]["value"], phase])
            else:
                notes.append(f"{key} order {row['order']} not determined by the log: left out")
        if rows:
            table[key] = rows
    return table, notes
