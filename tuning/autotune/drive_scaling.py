"""The tune job's scenario batches and observer settings scaled to the user's drive
([`pmsmjax.spec.drive_spec.DriveSpec`][pmsmjax.spec.drive_spec.DriveSpec]).

The controls' batches
([`tuning.autotune.scenario_batches.make_batch`][tuning.autotune.scenario_batches.make_batch]) take the drive
file's ``[tuning]`` ranges and control period as they are. The observer batches
([`tuning.autotune.observers`][tuning.autotune.observers],
[`tuning.autotune.hfi_tuning`][tuning.autotune.hfi_tuning]) were designed on the book drive in r/min, N m, A,
V and s; here each of their numbers becomes the same share of the user's drive: speeds of its rated speed (the
book's 1000 r/min), loads of its rated torque (10 N m), the measurement noise of its current limit (15 A) and
DC link (311 V), times (warm-up, hold, durations) of its tuning durations (the book's 0.3-0.5 s). On the book
drive every factor is exactly 1, so the batches are the book's to the bit
(tests/tuning/test_drive_scaling.py). The observer batches' top speed, twice the rated speed on the book
drive, is capped at the speed the inverter reaches under the rated torque (i_d = 0; 2119 r/min on the book
drive): beyond it the current loop saturates under a full load instead of testing the observer.

Objective weights ([`scaled_weights`][tuning.autotune.drive_scaling.scaled_weights]): the ITAE (rad s) of a
step grows with the speed and the square of the time scale, ``w t^2``, while the penalties are priced per % of
overshoot, per A over the limit, per unit of saturated time and per rad of angle error. Weights set on the
book drive (ITAE 0.03-0.3 rad s a scenario) price the penalties 40 times lower against the ITAE of a slow
heavy drive (industrial-5k6w: 1.6 rad s a scenario) and 7 times higher on a fast light one (outer-rotor-24v:
0.005 rad s; there 0.15 % of overshoot cost three times the whole ITAE, and BFGS found no accepted step
from the design rules, benchmarks/user_drive_tuning.py). The penalty weights are therefore scaled by the
drive's ITAE scale, ``(rated speed / 1000 r/min) (shortest tuning duration / 0.3 s)^2`` (1 on the book
drive).
"""

import dataclasses
import math

from pmsmjax.presets.book_constants import BOOK_CURRENT_LIMIT, BOOK_DC_LINK
from pmsmjax.spec.drive_spec import DriveSpec
from pmsmjax.spec.steady_state import top_speed_rpm

__all__ = [
    "operating_factors",
    "BOOK_RATED_SPEED_RPM",
    "BOOK_RATED_TORQUE_NM",
    "BOOK_TUNING_DURATION_S",
    "WORST_SHARE",
    "control_batch_options",
    "time_scale",
    "speed_scale",
    "torque_scale",
    "observer_top_speed_rpm",
    "noise_scale",
    "plant_spread",
    "itae_scale",
    "scaled_weights",
    "worst_share_mean",
]

#: The book drive's rated speed (r/min), rated torque (N m) and tuning durations (s): the units the observer
#: batches were designed in.
BOOK_RATED_SPEED_RPM = 1000.0
BOOK_RATED_TORQUE_NM = 10.0
BOOK_TUNING_DURATION_S = (0.3, 0.5)
#: The worst share of held-out scenarios whose mean cost is reported (the worst decile).
WORST_SHARE = 0.1


def control_batch_options(spec: DriveSpec) -> dict:
    """``make_batch`` keywords of the drive: ``speed_rpm``, ``load_nm``, ``duration_s`` (``[tuning]``) and
    ``Ts`` (the control period, s)."""
    t = spec.tuning
    return {
        "speed_rpm": tuple(t["speed_rpm"]),
        "load_nm": tuple(t["load_nm"]),
        "duration_s": tuple(t["duration_s"]),
        "Ts": spec.Ts,
    }


def time_scale(spec: DriveSpec) -> float:
    """The drive's shortest tuning duration over the book's 0.3 s (1 on the book drive)."""
    return spec.tuning["duration_s"][0] / BOOK_TUNING_DURATION_S[0]


def speed_scale(spec: DriveSpec) -> float:
    """The drive's rated speed over the book's 1000 r/min."""
    return spec.ratings["rated_speed_rpm"] / BOOK_RATED_SPEED_RPM


def torque_scale(spec: DriveSpec) -> float:
    """The drive's rated torque over the book's 10 N m."""
    return spec.ratings["rated_torque_nm"] / BOOK_RATED_TORQUE_NM


def observer_top_speed_rpm(spec: DriveSpec, book_top_rpm: float) -> float:
    """``book_top_rpm`` (a speed of the book drive's observer batches, r/min) on the drive: scaled by the
    rated speed, at most the top speed under the rated torque (module docstring)."""
    reach = top_speed_rpm(spec.motor, spec.voltage_limit_v, spec.ratings["rated_torque_nm"])
    return min(book_top_rpm * speed_scale(spec), reach)


def noise_scale(spec: DriveSpec) -> tuple[float, float]:
    """``(current, voltage)`` factors of the observers' measurement noise: the drive's current limit over
    the book's 15 A, its DC link over the book's 311 V."""
    return spec.current_limit_a / BOOK_CURRENT_LIMIT, spec.u_dc_v / BOOK_DC_LINK


#: The objective weights priced against the ITAE: the constraint penalties and the angle error.
PENALTY_WEIGHTS = (
    "overshoot",
    "current_penalty",
    "voltage_saturation_penalty",
    "angle_error",
    "margin_penalty",
)


def itae_scale(spec: DriveSpec) -> float:
    """The drive's ITAE scale over the book drive's: ``speed_scale x time_scale^2`` (module docstring)."""
    return speed_scale(spec) * time_scale(spec) ** 2


def scaled_weights(weights, spec: DriveSpec):
    """``weights`` ([`ObjectiveWeights`][tuning.autotune.objectives.ObjectiveWeights]) with `PENALTY_WEIGHTS`
    times [`itae_scale`][tuning.autotune.drive_scaling.itae_scale] (the same object on the book drive)."""
    scale = itae_scale(spec)
    if scale == 1.0:
        return weights
    return dataclasses.replace(weights, **{k: getattr(weights, k) * scale for k in PENALTY_WEIGHTS})


#: Tolerances of a drive file that a batch's plant draws can vary (the motor's parameters and the DC link).
_PLANT_KEYS_3 = ("R", "L_d", "L_q", "psi_f", "J", "B", "u_dc_v")
#: A compliant shaft's tolerances -> the motor parameters they scale ([`pmsmjax.machines.shaft`]).
_SHAFT_KEYS = {"load_inertia": "load_inertia", "shaft_stiffness_nm_per_rad": "shaft_stiffness"}


def plant_spread(spec: DriveSpec) -> dict:
    """``{parameter: relative half-width}`` of the drive file's ``[tolerances]`` that apply to its
    machine (``L_ls`` on a multi-phase motor only) and its current sensors (``current_offset_a``, an absolute
    half-width in A, and ``current_gain``), for ``make_batch(plant_spread=...)``, with the
    ``[operating]`` bands as ``(low, high)`` factors of the nominal value
    ([`operating_factors`][tuning.autotune.drive_scaling.operating_factors]; a DC-link band replaces the
    ``u_dc_v`` tolerance)."""
    keys = _PLANT_KEYS_3 + (("L_ls",) if spec.n_phases != 3 else ())
    keys += ("current_offset_a", "current_gain") if "current_offset_a" in spec.sensor else ()
    spread = {k: float(v) for k, v in spec.tolerances.items() if k in keys and v > 0}
    shaft = {_SHAFT_KEYS[k]: float(v) for k, v in spec.tolerances.items() if k in _SHAFT_KEYS and v > 0}
    return {**spread, **shaft, **operating_factors(spec)}


def operating_factors(spec: DriveSpec) -> dict:
    """The drive file's ``[operating]`` bands as ``{plant-scale name: (low, high)}`` factors of the drive's
    nominal values: ``u_dc_v`` of ``[inverter] u_dc_v``; the winding temperature (``initial_k``) of
    ``[thermal] initial_c`` and the ambient (``ambient_k``) of ``[thermal] ambient_c``, in kelvin (a uniform
    factor is a uniform temperature in the band)."""
    from pmsmjax.units import celsius_to_kelvin

    op = spec.operating
    out = {}
    if "u_dc_v" in op:
        out["u_dc_v"] = tuple(v / spec.u_dc_v for v in op["u_dc_v"])
    for key, name, nominal in (
        ("winding_temperature_c", "initial_k", "initial_c"),
        ("ambient_c", "ambient_k", "ambient_c"),
    ):
        if key in op:
            kelvin = celsius_to_kelvin(spec.thermal[nominal])
            out[name] = tuple(celsius_to_kelvin(v) / kelvin for v in op[key])
    return out


def worst_share_mean(costs, share: float = WORST_SHARE) -> float:
    """Mean of the worst ``share`` of ``costs`` (at least one): the worst-decile cost."""
    ordered = sorted((float(c) for c in costs), reverse=True)
    k = max(1, math.ceil(share * len(ordered) - 1e-9))
    return sum(ordered[:k]) / k
