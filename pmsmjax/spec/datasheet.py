"""Datasheet values in a drive file's ``[motor]``: the constants catalogues state, converted to pmsmjax's
``R`` (ohm, per phase), ``L_d``, ``L_q`` (H) and ``psi_f`` (Wb: the magnet's flux linkage, peak per phase,
amplitude-invariant dq, so that ``T = 1.5 p psi_f i_q`` with ``i_q`` the peak phase current at ``i_d = 0``).

Each key states its convention in its name; ``p`` is ``[motor] pole_pairs``:

- ``r_ll_ohm``, resistance between two terminals: ``R = r_ll / 2``. For a star winding that is two phases in
  series; for a delta winding (``r_ll = 2/3 R_delta``) it is the equivalent star's phase, ``R_delta / 3``:
  ``r_ll / 2`` either way.
- ``l_ll_h``, inductance between two terminals: ``L_d = L_q = l_ll / 2`` (the star-equivalent synchronous
  inductance, mutual coupling included). A salient motor's terminal inductance varies with rotor position
  between about ``2 L_d`` and ``2 L_q``: give ``L_d``, ``L_q`` instead.
- ``ke_v_peak_per_krpm_ll``, ``ke_v_rms_per_krpm_ll``: back-EMF between two terminals per 1000 r/min, as its
  peak or its RMS value (Kollmorgen's and Siemens' catalogues state RMS, drive parameters such as
  Kollmorgen AKD's ``MOTOR.KE`` peak). The line-to-line peak is ``sqrt(3)`` times the phase peak
  ``omega_e psi_f``, ``omega_e = p n 2 pi / 60``: ``psi_f = ke_peak / (sqrt(3) p 1000 2 pi / 60)``,
  ``ke_peak = sqrt(2) ke_rms``.
- ``kt_nm_per_a_rms``, ``kt_nm_per_a_peak``: torque per ampere of sinusoidal phase current at ``i_d = 0``,
  per A RMS (catalogues: Kollmorgen's ``KTrms``) or per A peak (drive firmware that works in dq amperes:
  ODrive, the MIT Cheetah-style controllers): ``psi_f = kt_peak / (1.5 p)``, ``kt_peak = kt_rms / sqrt(2)``.
- ``kv_rpm_per_v``, a hobby motor's speed constant: no-load r/min per volt. Read as r/min per volt of
  peak line-to-line back-EMF (with sinusoidal or space-vector drive the line-to-line peak reaches the DC
  link, so the no-load speed is about ``kv u_dc``): ``psi_f = 60 / (sqrt(3) 2 pi p kv)``, the same relation
  as ``kt_peak = 8.27 / kv`` (N m per A peak) that ODrive's users apply. VESC Tool's motor detection
  reports resistance, inductance (line to neutral) and "flux linkage" (Wb) itself: give those as ``R``,
  ``L_d = L_q`` and ``psi_f``.

The bare ``ke_v_per_krpm_ll`` and ``kt_nm_per_a`` are refused: datasheets use both conventions, and a peak
read as RMS is a 41 % error in the flux. A file may not give a datasheet key and the value it derives
(``r_ll_ohm`` and ``R``; ``l_ll_h`` and ``L_d`` or ``L_q``; a ``ke``, ``kt`` or ``kv`` and ``psi_f``), two
keys of one constant (both ``ke`` or both ``kt``), or a back-EMF and a torque constant (or ``kv``) whose flux
linkages differ by more than `CONSISTENCY` (for a surface-magnet motor they are the same ``psi_f``; a peak
read as RMS shows as a factor ``sqrt(2)``). ``psi_f`` then comes from the back-EMF constant (measured at no
load, free of saturation), else ``kv``, else ``kt``. Each derived value's note (``spec.derived``) states the
conversion.
"""

import math

from pmsmjax.spec.validation import ParameterError, plain

__all__ = ["DATASHEET_UNITS", "AMBIGUOUS", "CONSISTENCY", "refuse_ambiguous", "convert"]

#: The datasheet keys of ``[motor]`` and their units.
DATASHEET_UNITS = {
    "r_ll_ohm": "ohm",
    "l_ll_h": "H",
    "ke_v_peak_per_krpm_ll": "V/krpm",
    "ke_v_rms_per_krpm_ll": "V/krpm",
    "kt_nm_per_a_rms": "N m/A",
    "kt_nm_per_a_peak": "N m/A",
    "kv_rpm_per_v": "r/min/V",
}
#: Keys refused for their unstated convention, with the explicit ones to use.
AMBIGUOUS = {
    "ke_v_per_krpm_ll": ("ke_v_peak_per_krpm_ll", "ke_v_rms_per_krpm_ll", "V"),
    "kt_nm_per_a": ("kt_nm_per_a_rms", "kt_nm_per_a_peak", "A"),
}
#: Most relative difference accepted between the flux linkages two constants imply.
CONSISTENCY = 0.05
#: Mechanical rad/s at 1000 r/min.
KRPM_RAD_S = 1000.0 * 2.0 * math.pi / 60.0
SQRT2, SQRT3 = math.sqrt(2.0), math.sqrt(3.0)


def refuse_ambiguous(values: dict, where: str) -> None:
    """Refuse ``[motor]`` keys whose peak-or-RMS convention is not stated (`AMBIGUOUS`)."""
    for key, (peak_or_rms, other, unit) in AMBIGUOUS.items():
        if key in values:
            raise ParameterError(
                f"{where}: [motor] {key} does not say whether its {unit} are peak or RMS (datasheets use "
                f"both; a mix-up is a 41 % error): write {peak_or_rms} or {other} as your datasheet states."
            )


def _flux_linkages(values: dict, p: int) -> dict:
    """``{key: psi_f (Wb)}`` each given constant implies (module docstring)."""
    implied = {}
    if "ke_v_peak_per_krpm_ll" in values:
        implied["ke_v_peak_per_krpm_ll"] = values["ke_v_peak_per_krpm_ll"] / (SQRT3 * p * KRPM_RAD_S)
    if "ke_v_rms_per_krpm_ll" in values:
        implied["ke_v_rms_per_krpm_ll"] = SQRT2 * values["ke_v_rms_per_krpm_ll"] / (SQRT3 * p * KRPM_RAD_S)
    if "kv_rpm_per_v" in values:
        implied["kv_rpm_per_v"] = 60.0 / (SQRT3 * 2.0 * math.pi * p * values["kv_rpm_per_v"])
    if "kt_nm_per_a_peak" in values:
        implied["kt_nm_per_a_peak"] = values["kt_nm_per_a_peak"] / (1.5 * p)
    if "kt_nm_per_a_rms" in values:
        implied["kt_nm_per_a_rms"] = values["kt_nm_per_a_rms"] / (1.5 * SQRT2 * p)
    return implied


HOW = {
    "ke_v_peak_per_krpm_ll": "psi_f = ke / (sqrt(3) p 2 pi 1000/60) (peak line-to-line back-EMF)",
    "ke_v_rms_per_krpm_ll": "psi_f = sqrt(2) ke / (sqrt(3) p 2 pi 1000/60) (RMS line-to-line back-EMF)",
    "kv_rpm_per_v": "psi_f = 60 / (sqrt(3) 2 pi p kv) (r/min per volt of peak line-to-line back-EMF)",
    "kt_nm_per_a_peak": "psi_f = kt / (1.5 p) (torque per A peak phase current, i_d = 0)",
    "kt_nm_per_a_rms": "psi_f = kt / (1.5 sqrt(2) p) (torque per A RMS phase current, i_d = 0)",
}


def _hint(ratio: float) -> str:
    for factor, what in (
        (SQRT2, "sqrt(2): one is peak, the other RMS"),
        (2.0, "2: peak and RMS mixed twice"),
    ):
        if abs(ratio / factor - 1.0) < CONSISTENCY or abs(ratio * factor - 1.0) < CONSISTENCY:
            return f" (a factor {what}: check each key's convention against the datasheet)"
    return " (check each key's convention against the datasheet; if saturation lowers kt, give only the ke)"


def convert(values: dict, where: str) -> dict:
    """Replace ``[motor]``'s datasheet keys in ``values`` (the raw table, changed in place) by the SI values
    they give (module docstring).

    Args:
        values: the file's ``[motor]`` table.
        where: how messages name the file.

    Returns:
        ``{"motor.KEY": how}`` for every SI value derived.

    Raises:
        ParameterError: a datasheet key with the SI key it derives, two keys of one constant, constants that
            disagree, a value that is not a positive number, or a missing ``pole_pairs``.
    """
    given = {k: values[k] for k in DATASHEET_UNITS if k in values}
    if not given:
        return {}
    for key, value in given.items():
        unit = DATASHEET_UNITS[key]
        if (
            not isinstance(value, (int, float))
            or isinstance(value, bool)
            or not math.isfinite(value)
            or value <= 0
        ):
            raise ParameterError(f"{where}: [motor] {key} must be a number above 0 ({unit}), got {value!r}.")
    clashes = {"r_ll_ohm": ("R",), "l_ll_h": ("L_d", "L_q")}
    flux_keys = [k for k in HOW if k in given]
    for key, derived in [*clashes.items(), *((k, ("psi_f",)) for k in flux_keys)]:
        both = [d for d in derived if key in given and d in values]
        if both:
            raise ParameterError(
                f"{where}: [motor] gives both {key} and {', '.join(both)}, which it derives: keep one of "
                "them."
            )
    for pair in (("ke_v_peak_per_krpm_ll", "ke_v_rms_per_krpm_ll"), ("kt_nm_per_a_rms", "kt_nm_per_a_peak")):
        if all(k in given for k in pair):
            raise ParameterError(
                f"{where}: [motor] gives both {pair[0]} and {pair[1]}: keep the datasheet's one."
            )
    derived = {}
    if "r_ll_ohm" in given:
        values["R"] = given["r_ll_ohm"] / 2.0
        derived["motor.R"] = f"r_ll_ohm / 2 = {plain(given['r_ll_ohm'])} / 2 ohm (line-to-line resistance)"
    if "l_ll_h" in given:
        values["L_d"] = values["L_q"] = given["l_ll_h"] / 2.0
        how = f"l_ll_h / 2 = {plain(given['l_ll_h'])} / 2 H (line-to-line inductance, taken as non-salient)"
        derived["motor.L_d"] = derived["motor.L_q"] = how
    if flux_keys:
        p = values.get("pole_pairs")
        if not isinstance(p, int) or isinstance(p, bool) or p < 1:
            raise ParameterError(
                f"{where}: [motor] {flux_keys[0]} needs pole_pairs (a whole number >= 1) to give psi_f, "
                f"got {p!r}."
            )
        implied = _flux_linkages(given, p)
        first = flux_keys[0]
        for key in flux_keys[1:]:
            ratio = implied[key] / implied[first]
            if abs(ratio - 1.0) > CONSISTENCY:
                raise ParameterError(
                    f"{where}: [motor] {first} = {plain(given[first])} and {key} = {plain(given[key])} "
                    f"disagree: they give psi_f = {implied[first]:.4g} and {implied[key]:.4g} Wb "
                    f"({100 * (ratio - 1):+.0f} %, more than {100 * CONSISTENCY:.0f} %){_hint(ratio)}."
                )
        values["psi_f"] = implied[first]
        agree = [
            f"{k} agrees within {100 * abs(implied[k] / implied[first] - 1):.1f} %" for k in flux_keys[1:]
        ]
        derived["motor.psi_f"] = (
            f"from {first} = {plain(given[first])} {DATASHEET_UNITS[first]}: {HOW[first]}"
            + (f"; {', '.join(agree)}" if agree else "")
        )
    for key in given:
        del values[key]
    return derived
