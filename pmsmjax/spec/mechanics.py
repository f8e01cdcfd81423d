"""The drive file's compliant shaft (``[mechanics]``) and speed-loop filters (``[control]`` keys): read,
checked and completed, each refusal one line naming the key and the fix. Plain Python.

``[mechanics]``: ``load_inertia`` (kg m^2), ``shaft_stiffness_nm_per_rad`` (N m/rad),
``shaft_damping_nm_s_per_rad`` (N m s/rad, default 0: an undamped shaft, the worst case); ``[motor] J`` is
then the motor's own inertia (the design rules take the total, ``J + load_inertia``).

``[control]``: ``speed_filter_hz`` (a low-pass on the speed feedback), ``notch_hz``, ``notch_width_hz``
(default half the centre), ``notch_depth_db`` (default 20 dB): the filters of
[`pmsmjax.controllers.speed_filters`][pmsmjax.controllers.speed_filters], each below the speed loop's Nyquist
frequency (the control rate's: the drive files' speed loop runs every control period).
"""

import math

from pmsmjax.spec.validation import ParameterError, plain

__all__ = ["MECHANICS_UNITS", "FILTER_UNITS", "read_mechanics", "rigid_equivalent", "complete_filters"]

MECHANICS_UNITS = {
    "load_inertia": "kg m^2",
    "shaft_stiffness_nm_per_rad": "N m/rad",
    "shaft_damping_nm_s_per_rad": "N m s/rad",
}
FILTER_UNITS = {"speed_filter_hz": "Hz", "notch_hz": "Hz", "notch_width_hz": "Hz", "notch_depth_db": "dB"}
#: A shaft resonance outside this range (Hz) is refused: below it the "shaft" is a soft spring no servo
#: runs on (or K in N m/deg), above it the shaft is rigid for any speed loop (or K in N mm/rad).
RESONANCE_RANGE_HZ = (1.0, 20_000.0)
#: A load inertia beyond this many times the motor's is refused (servo sizing keeps it within 10-30).
MAX_INERTIA_RATIO = 1000.0
NOTCH_DEFAULTS = {"notch_width_hz": 0.5, "notch_depth_db": 20.0}


def read_mechanics(values: dict, motor: dict, where: str) -> dict:
    """The ``[mechanics]`` table checked against the motor: ``{load_inertia, shaft_stiffness,
    shaft_damping}`` in SI units (the motor parameters' names), or ``{}`` without the table."""
    if not values:
        return {}
    missing = [k for k in ("load_inertia", "shaft_stiffness_nm_per_rad") if k not in values]
    if missing:
        raise ParameterError(
            f"{where}: [mechanics] lacks {', '.join(missing)}: a compliant shaft needs load_inertia (kg m^2) "
            "and shaft_stiffness_nm_per_rad (N m/rad); drop [mechanics] for a rigid shaft."
        )
    if motor.get("n_phases", 3) != 3:
        raise ParameterError(
            f"{where}: [mechanics] (a compliant shaft) is modelled for three-phase motors; this motor has "
            f"{motor['n_phases']} phases: drop [mechanics]."
        )
    out = {}
    for key, unit in MECHANICS_UNITS.items():
        v = values.get(key, 0.0)
        ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
        if not ok or v < 0 or (v == 0 and key != "shaft_damping_nm_s_per_rad"):
            need = ">= 0" if key == "shaft_damping_nm_s_per_rad" else "> 0"
            raise ParameterError(f"{where}: [mechanics] {key} = {v!r}: give a finite number {need} ({unit}).")
        out[key] = float(v)
    J, J_L, K = motor["J"], out["load_inertia"], out["shaft_stiffness_nm_per_rad"]
    if J_L > MAX_INERTIA_RATIO * J:
        raise ParameterError(
            f"{where}: [mechanics] load_inertia = {plain(J_L)} kg m^2 is {J_L / J:.3g} times the motor's J = "
            f"{plain(J)}: give the load's inertia in kg m^2 (g cm^2 * 1e-7), reflected through any gearing."
        )
    f_r = math.sqrt(K * (J + J_L) / (J * J_L)) / (2 * math.pi)
    low, high = RESONANCE_RANGE_HZ
    if not low <= f_r <= high:
        raise ParameterError(
            f"{where}: [mechanics] shaft_stiffness_nm_per_rad = {plain(K)} gives a shaft resonance of "
            f"{f_r:.3g} Hz, outside {plain(low)}-{plain(high)} Hz: give the stiffness in N m/rad (N m/deg "
            "* 57.3), or drop [mechanics] for a rigid shaft."
        )
    return {"load_inertia": J_L, "shaft_stiffness": K, "shaft_damping": out["shaft_damping_nm_s_per_rad"]}


def rigid_equivalent(motor: dict, shaft: dict) -> dict:
    """``motor`` with ``J`` the total inertia of motor and load (what the design rules size the speed loop
    for); ``motor`` itself without a shaft."""
    return {**motor, "J": motor["J"] + shaft["load_inertia"]} if shaft else motor


def complete_filters(control: dict, Ts_speed: float, derived: dict, where: str) -> None:
    """Complete the notch's width and depth (noted in ``derived``) and refuse filters the speed loop cannot
    run: a notch width not below twice its centre, a depth beyond 60 dB, a frequency at or above the
    Nyquist frequency ``1 / (2 Ts_speed)``, a low-pass below the speed loop's bandwidth."""
    given = [k for k in FILTER_UNITS if k in control]
    if not given:
        return
    if "notch_hz" not in control and any(k.startswith("notch_") for k in given):
        raise ParameterError(
            f"{where}: [control] notch_width_hz and notch_depth_db shape a notch: give notch_hz (Hz, the "
            "shaft's resonance) too, or drop them."
        )
    if "notch_hz" in control:
        for key, share in NOTCH_DEFAULTS.items():
            if key not in control:
                control[key] = share * control["notch_hz"] if key == "notch_width_hz" else share
                derived[f"control.{key}"] = (
                    "half the notch frequency" if key == "notch_width_hz" else "20 dB at the notch frequency"
                )
    nyquist = 0.5 / Ts_speed
    for key in ("speed_filter_hz", "notch_hz"):
        if key in control and control[key] >= nyquist:
            raise ParameterError(
                f"{where}: [control] {key} = {plain(control[key])} Hz is at or above the speed loop's "
                f"Nyquist frequency {plain(nyquist)} Hz: give a frequency below it (in Hz, not rad/s)."
            )
    if "notch_hz" in control:
        if control["notch_width_hz"] >= 2.0 * control["notch_hz"]:
            raise ParameterError(
                f"{where}: [control] notch_width_hz = {plain(control['notch_width_hz'])} Hz is not below "
                f"twice notch_hz = {plain(control['notch_hz'])} Hz: give a narrower notch (half the centre "
                "is usual)."
            )
        if control["notch_depth_db"] > 60.0:
            raise ParameterError(
                f"{where}: [control] notch_depth_db = {plain(control['notch_depth_db'])} dB: give an "
                "attenuation in dB up to 60 (servo notches are 10-40 dB)."
            )
    bandwidth_hz = control["speed_bandwidth_rad_s"] / (2 * math.pi)
    if control.get("speed_filter_hz", math.inf) < bandwidth_hz:
        raise ParameterError(
            f"{where}: [control] speed_filter_hz = {plain(control['speed_filter_hz'])} Hz is below the speed "
            f"loop's bandwidth ({bandwidth_hz:.3g} Hz): a feedback filter that slow destabilises the loop; "
            "give 3-10 times the bandwidth (in Hz)."
        )
