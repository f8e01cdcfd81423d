"""What a drive file leaves out, derived from what it gives, and the checks that need the derived values:
the inverter's defaults, the ratings (rated current and torque from each other, the peak current, the DC
link and the base speed), a rated point the inverter cannot reach, the loops' bandwidths and the I/f start
(the rules: [`pmsmjax.spec.design_rules`][pmsmjax.spec.design_rules]), the flux map's linear model. Each
derived value is noted with how it was found (``DriveSpec.derived``). Plain Python."""

import math
from collections.abc import Mapping

from pmsmjax.spec import design_rules as rules
from pmsmjax.spec.schema import (
    DC_LINK_RANGE_V,
    FLUX_MAP_DERIVES,
    MAX_DEAD_TIME_SHARE,
    MAX_DEVICE_DROP_SHARE,
    MAX_DEVICE_DROP_V,
    MAX_SPEED_RPM,
    SWITCHING_RANGE_HZ,
    TABLES,
)
from pmsmjax.spec.steady_state import reachable, steady_point
from pmsmjax.spec.validation import ParameterError, plain

SCENARIO_HOW = {
    "speed_rpm": "the rated speed",
    "load_nm": f"{rules.DEMO_LOAD_SHARE:g} x the rated torque",
    "load_time_s": "twice the speed loop's settling from rest (full-torque acceleration + 4 / beta), "
    "rounded up to 1, 2, 2.5 or 5 x 10^k s",
    "duration_s": "twice the load time",
}
TUNING_HOW = {
    "speed_rpm": f"{rules.TUNING_SPEED_SHARES[0]:g} x rated to the lower of "
    f"{rules.TUNING_SPEED_SHARES[1]:g} x rated and the top speed at rated torque (i_d = 0)",
    "load_nm": "0 to the rated torque",
    "duration_s": f"{rules.TUNING_DURATION_FACTORS[0]:g} to {rules.TUNING_DURATION_FACTORS[1]:g} x the "
    "scenario rule's load time at rated speed",
}


def flux_map_motor(values: dict, ratings: dict, grid, map_path: str) -> dict:
    """Put the map ``grid``'s linear model (module docstring) into ``values`` where the file leaves it out;
    the map's absolute path ``map_path`` replaces the relative one. Returns the derivation notes."""
    current = ratings.get("rated_current_a", 0.0)
    if not isinstance(current, (int, float)) or isinstance(current, bool):
        current = 0.0  # refused with its own message when [ratings] is read
    at = f"i_d = 0, i_q = {current:g} A (the rated current)" if current else "zero current"
    linear = grid.linear_model(float(current))
    how = {
        "psi_f": "psi_d(0, 0) of the flux map",
        "L_d": f"the flux map's incremental dpsi_d/di_d at {at}",
        "L_q": f"the flux map's incremental dpsi_q/di_q at {at}",
    }
    derived = {}
    for key in FLUX_MAP_DERIVES:
        if key not in values:
            values[key] = linear[key]
            derived[f"motor.{key}"] = how[key]
    values["flux_map"] = map_path
    return derived


def namer(where: str, flags: Mapping[str, str], overrides: Mapping[str, float]):
    """How a message names a value: the flag that set it, else the file's table and key."""
    table_of = {
        key: table for table, keys in TABLES.items() for key in keys if table in ("ratings", "inverter")
    }

    def name_of(key: str) -> str:
        if key in overrides and key in flags:
            return flags[key]
        return f"{where}: [{table_of[key]}] {key}"

    return name_of


def complete_inverter(inverter: dict, derived: dict, name_of) -> None:
    """Refuse an implausible DC link, switching or control frequency, dead time or device drop (a unit
    slip), and fill in the inverter's defaults, each noted in ``derived``."""
    u_dc = inverter.get("u_dc_v")
    if u_dc is not None and not DC_LINK_RANGE_V[0] <= u_dc <= DC_LINK_RANGE_V[1]:
        hint = f": it looks like kV: write {plain(u_dc * 1e3)}" if u_dc * 1e3 <= DC_LINK_RANGE_V[1] else ""
        raise ParameterError(
            f"{name_of('u_dc_v')} = {plain(u_dc)} V is outside the {plain(DC_LINK_RANGE_V[0])}-"
            f"{plain(DC_LINK_RANGE_V[1])} V of drive DC links{hint} (V)."
        )
    for key in ("switching_frequency_hz", "control_frequency_hz"):
        f = inverter.get(key)
        if f is not None and not SWITCHING_RANGE_HZ[0] <= f <= SWITCHING_RANGE_HZ[1]:
            hint = f": it looks like kHz: write {plain(f * 1e3)}" if f * 1e3 <= SWITCHING_RANGE_HZ[1] else ""
            raise ParameterError(
                f"{name_of(key)} = {plain(f)} Hz is outside the {plain(SWITCHING_RANGE_HZ[0])} Hz-"
                f"{plain(SWITCHING_RANGE_HZ[1] / 1e3)} kHz of drive inverters{hint} (Hz)."
            )
    if "switching_frequency_hz" not in inverter:
        inverter["switching_frequency_hz"] = 10_000.0
        derived["inverter.switching_frequency_hz"] = (
            "the book's 10 kHz (no [inverter] switching_frequency_hz)"
        )
    if "control_frequency_hz" not in inverter:
        inverter["control_frequency_hz"] = inverter["switching_frequency_hz"]
        derived["inverter.control_frequency_hz"] = "the switching frequency (one update per PWM period)"
    f_sw, f_c = inverter["switching_frequency_hz"], inverter["control_frequency_hz"]
    if not f_sw / 10.0 <= f_c <= 2.0 * f_sw:
        raise ParameterError(
            f"{name_of('control_frequency_hz')} = {plain(f_c)} Hz: the control runs once or twice per PWM "
            f"period ({plain(f_sw)} Hz), or at most 10 periods apart; give {plain(f_sw)} or "
            f"{plain(2 * f_sw)}."
        )
    period = 1.0 / f_sw
    t_d = inverter.get("dead_time_s", 0.0)
    if "dead_time_s" not in inverter:
        inverter["dead_time_s"] = 0.0
        derived["inverter.dead_time_s"] = "0 (ideal switches)"
    if t_d > MAX_DEAD_TIME_SHARE * period:
        longer = "longer than" if t_d >= period else f"{100 * t_d / period:.0f} % of"
        raise ParameterError(
            f"{name_of('dead_time_s')} = {plain(t_d)} s is {longer} the {plain(period * 1e6)} us switching "
            f"period ({plain(f_sw / 1e3)} kHz): dead times are 0.1-5 us, in s: write e.g. 2e-6 for 2 us."
        )
    if "device_drop_v" not in inverter:
        inverter["device_drop_v"] = 0.0
        derived["inverter.device_drop_v"] = "0 (ideal switches)"
    drop, u_dc = inverter["device_drop_v"], inverter.get("u_dc_v")
    if drop > MAX_DEVICE_DROP_V or (u_dc is not None and drop > MAX_DEVICE_DROP_SHARE * u_dc):
        of_link = f" or {100 * MAX_DEVICE_DROP_SHARE:g} % of the {plain(u_dc)} V DC link" if u_dc else ""
        raise ParameterError(
            f"{name_of('device_drop_v')} = {plain(drop)} V is above {plain(MAX_DEVICE_DROP_V)} V{of_link}: a "
            "switch or diode drops 0.7-3 V (MOSFETs less), in V: write e.g. 1.5."
        )


def complete_ratings(motor: dict, ratings: dict, inverter: dict, derived: dict, name_of) -> None:
    """Refuse contradicting ratings and fill in those the file leaves out (rated current and torque
    from each other by MTPA, the peak current, the DC link, the base speed), each noted in ``derived``."""
    speed = ratings.get("rated_speed_rpm")
    if speed is not None and speed > MAX_SPEED_RPM:
        raise ParameterError(
            f"{name_of('rated_speed_rpm')} = {plain(speed)} r/min: give at most {plain(MAX_SPEED_RPM)}."
        )
    torque, current, peak = (ratings.get(k) for k in ("rated_torque_nm", "rated_current_a", "max_current_a"))
    if torque is not None and current is not None:
        can = rules.torque_at_current(motor, current)
        if torque > 1.05 * can:
            raise ParameterError(
                f"{name_of('rated_torque_nm')} = {plain(torque)} N m is more than rated_current_a = "
                f"{plain(current)} A gives ({can:.3g} N m with psi_f = {plain(motor['psi_f'])} Wb, "
                f"{motor['pole_pairs']} pole pairs): the ratings contradict each other; check psi_f (peak "
                "flux per phase, Wb) and the current (A peak, not RMS), or give only one of them."
            )
    elif torque is not None:
        ratings["rated_current_a"] = rules.current_for_torque(motor, torque)
        derived["ratings.rated_current_a"] = "the MTPA current of the rated torque"
    elif current is not None:
        ratings["rated_torque_nm"] = rules.torque_at_current(motor, current)
        derived["ratings.rated_torque_nm"] = "the MTPA torque of the rated current"
    elif peak is not None:
        ratings["rated_current_a"] = peak / rules.PEAK_TO_RATED_CURRENT
        ratings["rated_torque_nm"] = rules.torque_at_current(motor, ratings["rated_current_a"])
        derived["ratings.rated_current_a"] = f"max_current_a / {rules.PEAK_TO_RATED_CURRENT:g}"
        derived["ratings.rated_torque_nm"] = "the MTPA torque of the rated current"
    else:
        # Nothing about the current: take the book drive's ratio of rated current to the characteristic
        # current psi_f / L_d (9.1 A of 34.8 A) and say so loudly.
        ratings["rated_current_a"] = 0.26 * motor["psi_f"] / motor["L_d"]
        ratings["rated_torque_nm"] = rules.torque_at_current(motor, ratings["rated_current_a"])
        derived["ratings.rated_current_a"] = (
            "0.26 x the characteristic current psi_f / L_d (the book drive's ratio): a guess; give "
            "[ratings] rated_torque_nm or rated_current_a"
        )
        derived["ratings.rated_torque_nm"] = "the MTPA torque of the rated current"
    if peak is None:
        ratings["max_current_a"] = rules.PEAK_TO_RATED_CURRENT * ratings["rated_current_a"]
        derived["ratings.max_current_a"] = f"{rules.PEAK_TO_RATED_CURRENT:g} x the rated current"
    elif peak < ratings["rated_current_a"] * (1.0 - 1e-9):
        given = (
            "rated_current_a"
            if current is not None
            else f"the {plain(ratings['rated_torque_nm'])} N m rated torque's"
        )
        raise ParameterError(
            f"{name_of('max_current_a')} = {plain(peak)} A is below {given} "
            f"{ratings['rated_current_a']:.3g} A: "
            "the peak current must be at least the rated current (both A peak); raise max_current_a or "
            "lower the rating."
        )
    u_limit = None
    if "u_dc_v" not in inverter:
        if speed is None:
            inverter["u_dc_v"] = 311.0
            derived["inverter.u_dc_v"] = "the book's 311 V (rectified 220 V mains): give [inverter] u_dc_v"
        else:
            need = rules.rated_point_voltage_v(motor, speed, ratings["rated_torque_nm"])
            inverter["u_dc_v"] = math.ceil(1.1 * need / rules.voltage_limit_v(1.0, motor.get("n_phases", 3)))
            derived["inverter.u_dc_v"] = "the rated point's voltage with 10 % margin (no [inverter] u_dc_v)"
    u_limit = rules.voltage_limit_v(inverter["u_dc_v"], motor.get("n_phases", 3))
    if speed is None:
        ratings["rated_speed_rpm"] = round(
            rules.base_speed_rpm(motor, ratings["rated_torque_nm"], u_limit), 1
        )
        derived["ratings.rated_speed_rpm"] = (
            f"the base speed: the rated torque's MTPA point at {100 * rules.BASE_SPEED_VOLTAGE_SHARE:g} % of "
            "the voltage limit"
        )
        if ratings["rated_speed_rpm"] <= 0:
            raise ParameterError(
                f"{name_of('u_dc_v')} = {plain(inverter['u_dc_v'])} V cannot drive the rated current "
                f"{ratings['rated_current_a']:.3g} A through R = {plain(motor['R'])} ohm even at standstill: "
                "raise u_dc_v or check R (ohm) and the current (A peak)."
            )


def check_rated_point(motor: dict, ratings: dict, inverter: dict, name_of) -> list:
    """Refuse a rated point the inverter cannot reach within the maximum current, even with field
    weakening; a point that needs field weakening is kept with a note."""
    n = motor.get("n_phases", 3)
    u_limit = rules.voltage_limit_v(inverter["u_dc_v"], n)
    speed, torque = ratings["rated_speed_rpm"], ratings["rated_torque_nm"]
    need = rules.rated_point_voltage_v(motor, speed, torque)
    if need <= u_limit:
        return []
    fw = reachable(motor, speed, torque, u_limit, ratings["max_current_a"], field_weakening=True)
    if fw["ok"]:
        # reachable() gives the i_d of least voltage; the note gives the weakest field weakening that
        # suffices (the voltage falls monotonically from i_d = 0 to that point: bisection).
        enough, short = fw["i_d"], 0.0
        for _ in range(60):
            mid = 0.5 * (enough + short)
            if steady_point(motor, speed * rules.RPM, torque, mid)["voltage"] <= u_limit:
                enough = mid
            else:
                short = mid
        return [
            f"the rated point ({plain(speed)} r/min, {torque:.3g} N m) needs {need:.0f} V with MTPA, above "
            f"the {u_limit:.0f} V the inverter gives: it is reached with field weakening only (i_d = "
            f"{enough:.3g} A at least); run demo with --field-weakening"
        ]
    top = rules.base_speed_rpm(motor, torque, u_limit, voltage_share=1.0)
    u_need = math.ceil(need / rules.voltage_limit_v(1.0, n))
    raise ParameterError(
        f"{name_of('rated_speed_rpm')} = {plain(speed)} r/min at {torque:.3g} N m needs {need:.0f} V peak "
        f"per phase, and the inverter's u_dc_v = {plain(inverter['u_dc_v'])} V gives {u_limit:.0f} V (field "
        f"weakening within max_current_a = {plain(ratings['max_current_a'])} A does not close the gap): "
        f"raise u_dc_v to at least {u_need} V, or lower rated_speed_rpm to about {top:.0f} r/min."
    )


def complete_control(motor: dict, ratings: dict, control: dict, Ts: float, derived: dict, where: str) -> None:
    """Refuse loop bandwidths that leave no phase margin or no cascade, and fill in the design rules'
    bandwidths and I/f start where the file leaves them out, each noted in ``derived``."""
    given = control.get("current_bandwidth_rad_s")
    unstable = rules.current_bandwidth_rule(Ts, phase_margin_deg=0.0)
    if given is not None and given >= unstable:
        raise ParameterError(
            f"{where}: [control] current_bandwidth_rad_s = {plain(given)} rad/s leaves the current loop no "
            "phase "
            f"margin against its 1.5-period delay at {plain(1 / Ts)} Hz (it must stay below {unstable:.0f} "
            f"rad/s; the design rule gives {rules.current_bandwidth_rule(Ts):.0f}): check the unit (rad/s, "
            "not Hz x 1000) or leave it out."
        )
    if "current_bandwidth_rad_s" not in control:
        control["current_bandwidth_rad_s"] = rules.current_bandwidth_rule(Ts)
        derived["control.current_bandwidth_rad_s"] = (
            f"{rules.CURRENT_LOOP_PHASE_MARGIN_DEG:g} deg phase margin against the 1.5-period loop delay: "
            "(pi/2 - 65 deg) / (1.5 Ts)"
        )
    if "speed_bandwidth_rad_s" not in control:
        control["speed_bandwidth_rad_s"] = rules.speed_bandwidth_rule(
            motor, control["current_bandwidth_rad_s"], ratings["max_current_a"], ratings["rated_speed_rpm"]
        )
        derived["control.speed_bandwidth_rad_s"] = (
            "a step of a fifth of the rated speed reaches the current limit with the P part alone: "
            "k_t I_max / (J w_rated / 5), at most a tenth of the current loop's"
        )
    if not control["speed_bandwidth_rad_s"] < control["current_bandwidth_rad_s"]:
        raise ParameterError(
            f"{where}: [control] speed_bandwidth_rad_s = {plain(control['speed_bandwidth_rad_s'])} rad/s is "
            "not "
            f"below the current loop's {control['current_bandwidth_rad_s']:.0f} rad/s: a cascade needs the "
            "speed "
            "loop well inside the current loop (a tenth is usual); lower it or leave it out."
        )
    startup = rules.startup_rule(motor, ratings)
    for key, value in startup.items():
        if key not in control:
            control[key] = value
            derived[f"control.{key}"] = rules.STARTUP_HOW[key]
