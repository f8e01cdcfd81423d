"""Unit plausibility of user data: a motor or log whose numbers only make sense in another unit (an
inductance in mH, a time in ms) is refused with the likely mistake named, before anything runs.

The library works in SI units and accepts any positive value; these checks are for values a user typed
or logged, and every refusal says how to override it for a genuine but unusual machine: ``trust_units =
true`` in the motor file, or the ``--trust-units`` flag of the command.

Ranges (wide: they catch a factor 1000 slip, not an unusual motor):

- inductances ``L_d``, ``L_q``: at most 1 H (drives span about 10 uH to 0.3 H);
- the electrical time constant ``min(L_d, L_q) / R``: 10 us to 1 s, and at least half the control
  period (a current that settles within one sample cannot be controlled);
- stator resistance ``R``: at most 100 ohm; flux linkage ``psi_f``: at most 5 Wb (peak, per phase);
- a log's time step: at most 10 ms and at most the electrical time constant (drive logs are sampled at
  the control rate, 1-20 kHz);
- temperature coefficients (``[motor]``, 1/K): of ``R`` 0 to 0.01 (copper 0.00393, aluminium 0.0040:
  IEC 60028, IEC 60889), of ``psi_f`` -0.005 to 0 (sintered NdFeB -0.0010 to -0.0012, SmCo -0.0003, ferrite
  -0.0020: magnet makers' data sheets); a value 100 times larger is a coefficient in %/K;
- temperatures (degC): ambient -60 to 150, a winding -60 to 250 (insulation class H is rated 180 degC,
  IEC 60085), a reference -60 to 250; a value above 250 looks like kelvin;
- the thermal network: ``r_th`` 1e-4 to 100 K/W, ``c_th`` 0.1 J/K to 1e7 J/K (a 1 kW motor's winding:
  about 0.5 K/W and 1-5 kJ/K).

Pure Python: runs before JAX is imported.
"""

import math
from collections.abc import Mapping

from pmsmjax.spec.validation import ParameterError, plain

__all__ = [
    "check_motor_units",
    "check_flux_map_units",
    "check_time_step",
    "check_thermal_units",
    "OVERRIDE",
    "OVERRIDE_LOG",
]

#: How a refusal says to override it (motor files; logs).
OVERRIDE = "if the value is right, add trust_units = true to the motor file or pass --trust-units"
OVERRIDE_LOG = "if the steps really are that long, pass --trust-units"

MAX_INDUCTANCE_H = 1.0
MAX_RESISTANCE_OHM = 100.0
MAX_FLUX_WB = 5.0
TIME_CONSTANT_RANGE_S = (10e-6, 1.0)
MAX_LOG_STEP_S = 10e-3
#: Plausible temperature coefficients, 1/K, of the resistance and of the magnet flux.
R_TEMP_COEFF_RANGE = (0.0, 0.01)
PSI_F_TEMP_COEFF_RANGE = (-0.005, 0.0)
#: Plausible temperatures, degC: an ambient, a winding (and a reference temperature).
AMBIENT_RANGE_C = (-60.0, 150.0)
WINDING_RANGE_C = (-60.0, 250.0)
#: Plausible thermal resistance (K/W) and heat capacity (J/K) of a winding node.
R_TH_RANGE = (1e-4, 100.0)
C_TH_RANGE = (0.1, 1e7)


def _scaled(value: float, unit: str, factors) -> str:
    """``"mH: write 0.00525 (H)"`` for the first prefix that brings ``value`` into its plausible range."""
    for prefix, factor, ok in factors:
        if ok(value * factor):
            return f"it looks like {prefix}{unit}: write {plain(value * factor)} ({unit})"
    return f"check its unit ({unit})"


def check_motor_units(values: Mapping[str, float], source: str, Ts: float | None = None) -> None:
    """Refuse motor values (SI: ohm, H, Wb) that are implausible in SI units; `Ts` is the control period
    (s) when known. `source` names the data in the message (``motor file m.toml``)."""
    R = float(values["R"])
    for name in ("L_d", "L_q"):
        L = float(values[name])
        if L > MAX_INDUCTANCE_H:
            prefixes = (("m", 1e-3, lambda x: x <= MAX_INDUCTANCE_H), ("u", 1e-6, lambda x: True))
            raise ParameterError(
                f"{source}: {name} = {plain(L)} H is not a drive's inductance (at most "
                f"{plain(MAX_INDUCTANCE_H)} H; L/R would be {L / R:.3g} s): {_scaled(L, 'H', prefixes)}; "
                f"{OVERRIDE}."
            )
    if R > MAX_RESISTANCE_OHM:
        raise ParameterError(
            f"{source}: R = {plain(R)} ohm is not a drive's stator resistance (at most "
            f"{plain(MAX_RESISTANCE_OHM)} ohm): it looks like mohm: write {plain(R * 1e-3)} (ohm); "
            f"{OVERRIDE}."
        )
    psi = float(values["psi_f"])
    if psi > MAX_FLUX_WB:
        raise ParameterError(
            f"{source}: psi_f = {plain(psi)} Wb is not a magnet flux linkage (peak, per phase; at most "
            f"{plain(MAX_FLUX_WB)} Wb, 0.1827 for the book motor): it looks like mWb "
            f"({plain(psi * 1e-3)} Wb) or a back-EMF constant; {OVERRIDE}."
        )
    L = min(float(values["L_d"]), float(values["L_q"]))
    tau = L / R
    lo, hi = TIME_CONSTANT_RANGE_S
    floor = max(lo, 0.5 * Ts) if Ts else lo
    if tau < floor:
        period = f" and half the {plain(Ts * 1e6)} us control period" if Ts and 0.5 * Ts > lo else ""
        raise ParameterError(
            f"{source}: the electrical time constant min(L_d, L_q)/R = {tau * 1e6:.3g} us is shorter than "
            f"{plain(lo * 1e6)} us{period} (L = {plain(L)} H, R = {plain(R)} ohm): inductances are in H "
            f"(mH * 1e-3), resistance in ohm; {OVERRIDE}."
        )
    if tau > hi:
        raise ParameterError(
            f"{source}: the electrical time constant min(L_d, L_q)/R = {tau:.3g} s is longer than "
            f"{plain(hi)} s (L = {plain(L)} H, R = {plain(R)} ohm): check that L is in H and R in ohm; "
            f"{OVERRIDE}."
        )


def check_flux_map_units(psi_peak_wb: float, source: str) -> None:
    """Refuse a flux map whose largest flux linkage ``psi_peak_wb`` (the largest magnitude of its psi_d and
    psi_q columns, read as Wb) is beyond `MAX_FLUX_WB`: written in mWb. Checked before the map's L_d, L_q
    and psi_f are derived, so that the message names the map's columns, not values the file never wrote."""
    if psi_peak_wb > MAX_FLUX_WB:
        raise ParameterError(
            f"{source}: its psi_d, psi_q columns reach {plain(psi_peak_wb)} Wb, beyond any drive's flux "
            f"linkage (at most {plain(MAX_FLUX_WB)} Wb, peak per phase): they look like mWb: divide them by "
            f"1000 (Wb); {OVERRIDE}."
        )


def check_time_step(step_s: float, source: str, time_constant_s: float | None = None, how: str = "") -> None:
    """Refuse a log whose median time step ``step_s`` (in the log's time unit, read as s) is implausible for
    a drive log; `time_constant_s` is the motor's electrical time constant when known. `how` says how to
    give the time unit (``--time-unit ms``)."""
    if not math.isfinite(step_s) or step_s <= 0:
        return
    limit = MAX_LOG_STEP_S if time_constant_s is None else max(MAX_LOG_STEP_S, time_constant_s)
    if step_s <= limit:
        return
    unit = next((u for u, f in (("ms", 1e-3), ("us", 1e-6)) if step_s * f <= limit), None)
    guess = f"time looks like it is in {unit} ({plain(step_s)} {unit} steps)" if unit else "check its unit"
    fix = how.format(unit=unit) if how and unit else "convert the time column to seconds"
    tau = ""
    if time_constant_s:
        tau = f" and the motor's electrical time constant is {time_constant_s * 1e3:.3g} ms"
    raise ParameterError(
        f"{source}: the time column steps by {plain(step_s)} s (median), but a drive log is sampled at the "
        f"control rate (0.05-1 ms){tau}: {guess}: {fix}; {OVERRIDE_LOG}."
    )


def check_thermal_units(
    temperature: Mapping[str, float],
    thermal: Mapping[str, float],
    operating: Mapping,
    where: str,
    trust=False,
) -> None:
    """Refuse temperature coefficients, temperatures and thermal values that are implausible in their
    units (a coefficient in %/K, a temperature in K), each naming the key, the value and the fix.

    A coefficient of the wrong sign (a resistance that falls, a magnet that gains flux when warm) is refused
    always; a magnitude out of range unless ``trust``.

    Args:
        temperature: ``[motor]``'s ``reference_temperature_c``, ``r_temp_coeff_per_k``,
            ``psi_f_temp_coeff_per_k`` (those given).
        thermal: the ``[thermal]`` table (``r_th_k_per_w``, ``c_th_j_per_k``, ``ambient_c``, ``initial_c``).
        operating: the ``[operating]`` table (``[low, high]`` ranges).
        where: how messages name the file.
        trust: the file says ``trust_units = true`` (or ``--trust-units``).
    """
    alpha = temperature.get("r_temp_coeff_per_k")
    if alpha is not None:
        name = f"{where}: [motor] r_temp_coeff_per_k = {plain(alpha)} /K"
        if alpha < 0:
            raise ParameterError(
                f"{name}: a winding's resistance rises with temperature: give a value >= 0 (copper 0.00393)."
            )
        if alpha > R_TEMP_COEFF_RANGE[1] and not trust:
            raise ParameterError(
                f"{name} is beyond any conductor's (copper 0.00393 /K): it looks like %/K: write "
                f"{plain(alpha / 100)} (1/K); {OVERRIDE}."
            )
    beta = temperature.get("psi_f_temp_coeff_per_k")
    if beta is not None:
        name = f"{where}: [motor] psi_f_temp_coeff_per_k = {plain(beta)} /K"
        if beta > 0:
            raise ParameterError(
                f"{name}: a magnet's flux falls with temperature: give a value <= 0 (sintered NdFeB -0.0011, "
                "SmCo -0.0003)."
            )
        if beta < PSI_F_TEMP_COEFF_RANGE[0] and not trust:
            raise ParameterError(
                f"{name} is beyond any magnet's (NdFeB -0.0010 to -0.0012 /K): it looks like %/K: write "
                f"{plain(beta / 100)} (1/K); {OVERRIDE}."
            )
    checks = [
        ("motor", "reference_temperature_c", temperature.get("reference_temperature_c"), WINDING_RANGE_C)
    ]
    checks += [("thermal", "ambient_c", thermal.get("ambient_c"), AMBIENT_RANGE_C)]
    checks += [("thermal", "initial_c", thermal.get("initial_c"), WINDING_RANGE_C)]
    for key, span in (("winding_temperature_c", WINDING_RANGE_C), ("ambient_c", AMBIENT_RANGE_C)):
        for value in operating.get(key, ()):
            checks.append(("operating", key, value, span))
    for table, key, value, (lo, hi) in checks:
        if value is None or lo <= value <= hi or trust:
            continue
        kelvin = f": it looks like kelvin: write {plain(value - 273.15)} (degC)" if value > hi else ""
        raise ParameterError(
            f"{where}: [{table}] {key} = {plain(value)} degC is outside the {plain(lo)} to {plain(hi)} degC "
            f"of a motor's{kelvin}; {OVERRIDE}."
        )
    for key, unit, (lo, hi) in (("r_th_k_per_w", "K/W", R_TH_RANGE), ("c_th_j_per_k", "J/K", C_TH_RANGE)):
        value = thermal.get(key)
        if value is not None and not lo <= value <= hi and not trust:
            raise ParameterError(
                f"{where}: [thermal] {key} = {plain(value)} {unit} is outside the {plain(lo)} to {plain(hi)} "
                f"{unit} of a winding (a 1 kW motor: about 0.5 K/W and 1-5 kJ/K): check its unit; {OVERRIDE}."
            )
