"""What a drive can do and how to control it, from its motor and inverter: the ratings a drive file leaves
out, the design-rule bandwidths, and the scenarios every command runs. Pure Python (no JAX), so the
command line derives and checks a drive before anything compiles.

Motors are dicts of SI values (``R, L_d, L_q, psi_f, pole_pairs, J, B``; a multi-phase motor adds
``n_phases``), steady states those of [`pmsmjax.analysis.operating_point`][pmsmjax.analysis.operating_point].

**Torque per current** (the book, ch. 1, MTPA of chapter 2): ``T = (n/2) p i_q (psi_f + (L_d - L_q)
i_d)``, with the MTPA d-axis current for a current magnitude ``I``::

    i_d = (psi_f - sqrt(psi_f^2 + 8 (L_q - L_d)^2 I^2)) / (4 (L_q - L_d))      (0 for L_d = L_q)

**A flux map** (``motor["flux_map"]``, the map file's path, as a drive file with ``[motor] flux_map`` has
it): the MTPA rules ([`mtpa_d_current`][pmsmjax.spec.design_rules.mtpa_d_current],
[`torque_at_current`][pmsmjax.spec.design_rules.torque_at_current],
[`current_for_torque`][pmsmjax.spec.design_rules.current_for_torque]) and the rated point's voltage
``|R i + w_e J psi(i)|`` ([`rated_point_voltage_v`][pmsmjax.spec.design_rules.rated_point_voltage_v], hence
the base speed) come from the map's MTPA table
([`pmsmjax.controllers.flux_map_loci`][pmsmjax.controllers.flux_map_loci], built once per map up to the grid's
corner current; the torque is held beyond it) instead of the linear model; the other rules keep the linear
model the map derives (``psi_f``, ``L_d``, ``L_q``). The map's interpolant, torque and voltage are the plant's
own ([`pmsmjax.machines.flux_map`][pmsmjax.machines.flux_map],
[`pmsmjax.machines.dq_equations`][pmsmjax.machines.dq_equations]), evaluated in NumPy: this path, too, loads
no JAX.

**Current-loop bandwidth** ([`current_bandwidth_rule`][pmsmjax.spec.design_rules.current_bandwidth_rule]):
the internal-model PI of the book, ch. 3 makes the current loop ``a_c / s`` times the loop's delay, one period
of computation plus half a period of the PWM's zero-order hold, ``1.5 Ts``; its phase margin is
``90 deg - 1.5 Ts a_c`` (rad). The rule keeps
[`CURRENT_LOOP_PHASE_MARGIN_DEG`][pmsmjax.spec.design_rules.CURRENT_LOOP_PHASE_MARGIN_DEG] = 65 deg:
``a_c = (pi/2 - 65 deg) / (1.5 Ts) = 0.29 / Ts`` (2.9 krad/s at 10 kHz). Harnefors and Nee, "Model-based
current control of AC machines using the internal model control method", IEEE TIA 34(1), 1998,
DOI 10.1109/28.658735 (the IMC design); the delay margin is the usual discrete-time bound (Harnefors et al.,
"Speed control of electrical drives using classical control methods", IEEE TIA 49(2), 2013,
DOI 10.1109/TIA.2012.2235185, which also asks the speed loop to stay well below the current loop).

**Speed-loop bandwidth** ([`speed_bandwidth_rule`][pmsmjax.spec.design_rules.speed_bandwidth_rule]): the
active-damping PI (the book, ch. 3) asks ``Kp omega = beta J omega / k_t`` of current on a speed step
``omega``; the rule takes the largest ``beta`` that keeps a step of a fifth of the rated speed inside the
current limit (linear, no wind-up), ``beta = T_max / (J omega_rated / 5)``: five times the inverse of the time
the drive needs to accelerate to rated speed at full torque (its mechanical time constant under the limit).
Larger steps ride on the current limit, which the realisable-reference anti-windup of the speed PI handles. At
most a tenth of the current loop's bandwidth. (The book's 50 rad/s keeps the whole 1000 r/min step linear:
16.4 N m / (0.003 kg m^2 x 104.7 rad/s) = 52 rad/s.)

**Scenarios** ([`default_scenario`][pmsmjax.spec.design_rules.default_scenario],
[`tuning_ranges`][pmsmjax.spec.design_rules.tuning_ranges]): the speed step goes to the rated speed, the
load to 0.8 of the rated torque; the load steps in after twice the time the speed loop needs to settle
(acceleration at full torque plus ``4 / beta``), rounded up to 1, 2, 2.5 or 5 x 10^k s, and the run lasts
twice that. Tuning batches draw speeds from 0.2 x rated to the rated speed or the top speed the inverter
reaches at rated torque (i_d = 0), whichever is lower, loads up to the rated torque, and durations of 1.5
to 2.5 x the load time. (The book drive file states the book's own ranges: steps of 200-1500 r/min, 0-10 N
m, 0.3-0.5 s.)
"""

import functools
import math
from collections.abc import Mapping

import numpy as np

from pmsmjax.machines import dq_equations as dq
from pmsmjax.spec.steady_state import steady_point, top_speed_rpm

__all__ = [
    "CURRENT_LOOP_PHASE_MARGIN_DEG",
    "PEAK_TO_RATED_CURRENT",
    "torque_factor",
    "mtpa_d_current",
    "torque_at_current",
    "current_for_torque",
    "voltage_limit_v",
    "rated_point_voltage_v",
    "base_speed_rpm",
    "current_bandwidth_rule",
    "speed_bandwidth_rule",
    "default_scenario",
    "tuning_ranges",
    "round_up_nice",
    "startup_rule",
    "common_period_s",
    "whole_period_speed_rpm",
]

RPM = math.pi / 30.0
#: Phase margin the current-loop rule keeps against the 1.5-period loop delay, degrees.
CURRENT_LOOP_PHASE_MARGIN_DEG = 65.0
#: Peak current over rated current when a drive file gives only one of them (servo-class inverters
#: allow 2-3x for seconds; 2 leaves the rated point linear with room to accelerate).
PEAK_TO_RATED_CURRENT = 2.0
#: Share of the voltage limit the rated point may use when the rated speed is derived (base speed).
BASE_SPEED_VOLTAGE_SHARE = 0.95
#: The speed step, as a share of the rated speed, that the speed-loop rule keeps linear.
SPEED_RULE_STEP_SHARE = 0.2
#: Speed-loop bandwidth at most this share of the current loop's (cascade separation).
SPEED_TO_CURRENT_BANDWIDTH = 0.1
#: Demo load as a share of the rated torque.
DEMO_LOAD_SHARE = 0.8
#: Tuning speed range as shares of the rated speed (steps up to the rated speed).
TUNING_SPEED_SHARES = (0.2, 1.0)
#: Tuning durations as multiples of the load-step time.
TUNING_DURATION_FACTORS = (1.5, 2.5)


def torque_factor(motor: Mapping) -> float:
    """``(n/2) p``: torque per ampere of q current per weber of flux (``1.5 p`` for three phases)."""
    return dq.torque_factor(motor["pole_pairs"], motor.get("n_phases", 3))


@functools.lru_cache(maxsize=8)
def _map_loci(path: str, pole_pairs: int):
    """``(MapTorque, MTPATable)`` of the flux map file ``path`` (module docstring, "A flux map")."""
    from pmsmjax.controllers.flux_map_loci import MapTorque, mtpa_table
    from pmsmjax.io.flux_map_files import read_flux_map

    grid = read_flux_map(path)
    corner = max(math.hypot(d, q) for d in (grid.i_d[0], grid.i_d[-1]) for q in (grid.i_q[0], grid.i_q[-1]))
    return MapTorque(grid, pole_pairs), mtpa_table(grid, pole_pairs, corner)


def _map_mtpa(motor: Mapping):
    """The MTPA table of ``motor``'s flux map, or None without one."""
    return _map_loci(str(motor["flux_map"]), motor["pole_pairs"])[1] if "flux_map" in motor else None


def mtpa_d_current(motor: Mapping, current_a: float) -> float:
    """The MTPA d-axis current (A, <= 0 for L_q > L_d) for a current magnitude ``current_a`` (module
    docstring); 0 for a surface motor. From the flux map's table when ``motor`` has one."""
    table = _map_mtpa(motor)
    if table is not None:
        motoring = table.i_q >= 0
        return float(np.interp(current_a, table.current[motoring], table.i_d[motoring]))
    saliency = motor["L_q"] - motor["L_d"]
    if abs(saliency) < 1e-12 * max(motor["L_q"], motor["L_d"]):
        return 0.0
    psi = motor["psi_f"]
    return (psi - math.sqrt(psi * psi + 8.0 * saliency * saliency * current_a * current_a)) / (4.0 * saliency)


def torque_at_current(motor: Mapping, current_a: float) -> float:
    """The most torque (N m) a current magnitude ``current_a`` (A, peak) gives (MTPA; the flux map's when
    ``motor`` has one)."""
    table = _map_mtpa(motor)
    if table is not None:
        return table.torque_at_current(current_a)
    i_d = mtpa_d_current(motor, current_a)
    i_q = math.sqrt(max(current_a * current_a - i_d * i_d, 0.0))
    psi_a = dq.active_flux(motor["psi_f"], motor["L_d"], motor["L_q"], i_d)
    return dq.active_flux_torque(torque_factor(motor), i_q, psi_a)


def current_for_torque(motor: Mapping, torque_nm: float) -> float:
    """The least current magnitude (A, peak) that gives ``torque_nm`` (MTPA; bisection, or the flux map's
    table when ``motor`` has one)."""
    table = _map_mtpa(motor)
    if table is not None:
        return table.current_for_torque(torque_nm)
    lo, hi = 0.0, max(torque_nm / (torque_factor(motor) * motor["psi_f"]), 1e-9)
    while torque_at_current(motor, hi) < torque_nm:
        lo, hi = hi, 2.0 * hi
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if torque_at_current(motor, mid) < torque_nm else (lo, mid)
    return hi


def voltage_limit_v(u_dc_v: float, n_phases: int = 3) -> float:
    """Peak phase voltage of the default modulator's linear range, V: ``U_dc / sqrt 3`` (SVPWM; the
    six-phase four-vector SVPWM likewise) or ``U_dc / (2 cos(pi/10))`` (five-phase near-four-vector)."""
    if n_phases == 5:
        return u_dc_v / (2.0 * math.cos(math.pi / 10.0))
    return u_dc_v / math.sqrt(3.0)


def rated_point_voltage_v(motor: Mapping, speed_rpm: float, torque_nm: float) -> float:
    """Peak phase voltage (V) the steady state at ``speed_rpm`` under ``torque_nm`` needs with MTPA
    currents (friction included)."""
    w = speed_rpm * RPM
    table = _map_mtpa(motor)
    if table is not None:
        i_d, i_q = table.point_for_torque(torque_nm + motor["B"] * w)
        psi, _ = _map_loci(str(motor["flux_map"]), motor["pole_pairs"])[0].flux(i_d, i_q)
        return dq.voltage_magnitude(motor["R"], motor["pole_pairs"] * w, i_d, i_q, psi[0], psi[1])
    current = current_for_torque(motor, torque_nm + motor["B"] * w)
    i_d = mtpa_d_current(motor, current)
    return steady_point(motor, w, torque_nm, i_d)["voltage"]


def base_speed_rpm(
    motor: Mapping, torque_nm: float, u_limit_v: float, voltage_share: float = BASE_SPEED_VOLTAGE_SHARE
) -> float:
    """The speed (r/min) at which the MTPA steady state under ``torque_nm`` needs ``voltage_share`` of
    ``u_limit_v``; 0 if standstill needs more."""
    target = voltage_share * u_limit_v
    if rated_point_voltage_v(motor, 0.0, torque_nm) > target:
        return 0.0
    lo, hi = 0.0, 100.0
    while rated_point_voltage_v(motor, hi, torque_nm) <= target and hi < 1e7:
        lo, hi = hi, 2.0 * hi
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if rated_point_voltage_v(motor, mid, torque_nm) <= target else (lo, mid)
    return lo


def current_bandwidth_rule(
    Ts: float, delay_periods: float = 1.5, phase_margin_deg: float = CURRENT_LOOP_PHASE_MARGIN_DEG
) -> float:
    """Current-loop bandwidth a_c (rad/s) for control period ``Ts`` (s): ``phase_margin_deg`` (default
    [`CURRENT_LOOP_PHASE_MARGIN_DEG`][pmsmjax.spec.design_rules.CURRENT_LOOP_PHASE_MARGIN_DEG]) against a
    loop delay of ``delay_periods`` periods (module docstring); ``phase_margin_deg=0`` gives the stability
    bound."""
    return (math.pi / 2.0 - math.radians(phase_margin_deg)) / (delay_periods * Ts)


def speed_bandwidth_rule(
    motor: Mapping, current_bandwidth_rad_s: float, max_current_a: float, rated_speed_rpm: float
) -> float:
    """Speed-loop bandwidth beta (rad/s): a step of `SPEED_RULE_STEP_SHARE` of the rated speed reaches
    the current limit with the P part alone; at most a tenth of the current loop's (module docstring)."""
    k_t = torque_factor(motor) * motor["psi_f"]  # the active-damping design's linear torque constant
    beta = k_t * max_current_a / (motor["J"] * SPEED_RULE_STEP_SHARE * rated_speed_rpm * RPM)
    return min(beta, SPEED_TO_CURRENT_BANDWIDTH * current_bandwidth_rad_s)


#: I/f start-up of a sensorless drive
#: ([`pmsmjax.estimators.startup.StartupEstimator`][pmsmjax.estimators.startup.StartupEstimator]): the current
#: as a share of the maximum, the ramp's acceleration as a share of what that current's torque gives the bare
#: rotor, the hand-over and blend speeds as shares of the rated speed (the book drive states its own: 8 A,
#: 1000 rad/s^2, 150 and 100 r/min).
STARTUP_SHARES = {"current": 0.5, "acceleration": 0.3, "handover": 0.15, "blend": 0.1}
STARTUP_HOW = {
    "startup_current_a": f"{STARTUP_SHARES['current']:g} x max_current_a",
    "startup_acceleration_rad_s2": f"{STARTUP_SHARES['acceleration']:g} x the start current's torque / J",
    "handover_speed_rad_s": f"{STARTUP_SHARES['handover']:g} x the rated speed",
    "blend_speed_rad_s": f"{STARTUP_SHARES['blend']:g} x the rated speed",
}


def startup_rule(motor: Mapping, ratings: Mapping) -> dict:
    """``{startup_current_a, startup_acceleration_rad_s2, handover_speed_rad_s, blend_speed_rad_s}`` of
    the I/f start (`STARTUP_SHARES`; speeds mechanical)."""
    current = STARTUP_SHARES["current"] * ratings["max_current_a"]
    rated = ratings["rated_speed_rpm"] * RPM
    return {
        "startup_current_a": current,
        "startup_acceleration_rad_s2": STARTUP_SHARES["acceleration"]
        * torque_at_current(motor, current)
        / motor["J"],
        "handover_speed_rad_s": STARTUP_SHARES["handover"] * rated,
        "blend_speed_rad_s": STARTUP_SHARES["blend"] * rated,
    }


def whole_period_speed_rpm(speed_rpm: float, pole_pairs: int, Ts: float, cycles: int = 2) -> float:
    """The highest speed (r/min, sign of ``speed_rpm``) at most ``|speed_rpm|`` whose ``cycles`` electrical
    periods span a whole number of control periods ``Ts`` (s): what a ripple or spectrum window over whole
    electrical periods sampled at the control rate needs. ``speed_rpm`` itself when it fits."""
    periods = cycles * 60.0 / (abs(speed_rpm) * pole_pairs * Ts)
    whole = round(periods)
    if abs(periods - whole) > 1e-6 * periods:
        whole = math.ceil(periods)
    return (
        math.copysign(cycles * 60.0 / (whole * pole_pairs * Ts), speed_rpm) if whole != periods else speed_rpm
    )


def common_period_s(periods_s) -> float:
    """The shortest time (s) that is a whole number of each of ``periods_s`` (s; the least common
    multiple, counted in nanoseconds)."""
    ns = [round(p * 1e9) for p in periods_s]
    return math.lcm(*ns) * 1e-9


def round_up_nice(x: float) -> float:
    """The smallest of 1, 2, 2.5, 5 x 10^k at least ``x`` (> 0), as the decimal a user would type."""
    k = math.floor(math.log10(x))
    for step in (1.0, 2.0, 2.5, 5.0, 10.0):
        value = float(f"{step}e{k}")
        if value >= x * (1.0 - 1e-12):
            return value
    return float(f"1e{k + 1}")  # pragma: no cover (10 x 10^k always fits)


def load_time_s(
    motor: Mapping, max_current_a: float, speed_rpm: float, speed_bandwidth_rad_s: float
) -> float:
    """When a scenario's load steps in, s: twice the time the speed loop needs to reach ``speed_rpm``
    from rest (acceleration at the current limit's torque, then ``4 / beta``), rounded up nicely."""
    accelerate = motor["J"] * abs(speed_rpm) * RPM / torque_at_current(motor, max_current_a)
    return round_up_nice(2.0 * (accelerate + 4.0 / speed_bandwidth_rad_s))


def default_scenario(
    motor: Mapping,
    rated_speed_rpm: float,
    rated_torque_nm: float,
    max_current_a: float,
    speed_bandwidth_rad_s: float,
) -> dict:
    """``{speed_rpm, load_nm, load_time_s, duration_s}`` of the drive's demo run (module docstring)."""
    t_load = load_time_s(motor, max_current_a, rated_speed_rpm, speed_bandwidth_rad_s)
    return {
        "speed_rpm": rated_speed_rpm,
        "load_nm": DEMO_LOAD_SHARE * rated_torque_nm,
        "load_time_s": t_load,
        "duration_s": 2.0 * t_load,
    }


def tuning_ranges(
    motor: Mapping,
    rated_speed_rpm: float,
    rated_torque_nm: float,
    max_current_a: float,
    u_dc_v: float,
    speed_bandwidth_rad_s: float,
) -> dict:
    """``{speed_rpm: [low, high], load_nm: [0, rated], duration_s: [low, high]}`` of the tuning batches
    (module docstring)."""
    top = top_speed_rpm(motor, voltage_limit_v(u_dc_v, motor.get("n_phases", 3)), rated_torque_nm)
    low, high = (share * rated_speed_rpm for share in TUNING_SPEED_SHARES)
    high = min(high, top)
    t_load = load_time_s(motor, max_current_a, rated_speed_rpm, speed_bandwidth_rad_s)
    return {
        "speed_rpm": [low, high],
        "load_nm": [0.0, rated_torque_nm],
        "duration_s": [float(f"{factor * t_load:.12g}") for factor in TUNING_DURATION_FACTORS],
    }
