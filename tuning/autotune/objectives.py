"""Tuning objectives: per-scenario figures of merit of a batch run, weighted into one cost.

Every metric is a jnp function of one scenario's trace, evaluated only over that scenario's own duration
([`ScenarioBatch.active`][tuning.autotune.scenario_batches.ScenarioBatch.active]), and vmapped over the batch.
The costs are differentiable almost everywhere; the hard constraints of a drive (current limit, voltage
saturation, overshoot) enter as penalties beyond their thresholds (linear; optionally rounded at the threshold
for quasi-Newton methods, [`smoothed_penalty`][tuning.autotune.objectives.smoothed_penalty]; the current
limit's rounding lies inside the limit), so a gradient pushes back as soon as they are crossed.
"""

import dataclasses
from typing import Literal

import jax
import jax.numpy as jnp
import numpy as np

import pmsmjax
from pmsmjax.analysis import metrics, observer_errors
from pmsmjax.drive import Drive
from pmsmjax.spec.validation import ParameterError
from pmsmjax.trace import Trace
from tuning.autotune.scenario_batches import SENSOR_SPREADS, ScenarioBatch
from tuning.parameters import get_leaf, set_leaves

METRIC_NAMES = (
    "itae",  # rad s (speed error in rad/s, weighted by time)
    "iae",  # rad
    "ise",  # rad^2/s
    "overshoot_pct",  # % of the step, in the window before the load change
    # the same before clipping at 0: negative (the speed stays below the step) only when the pre-load
    # window spans the whole record, since the samples after it count as 0 (scenario_metrics)
    "overshoot_signed_pct",
    "settling_time_s",  # s, 2 % band, in the window before the load change
    "peak_current_a",  # A, largest phase current
    "rms_current_a",  # A
    "current_excess_a",  # A above the current limit (0 when respected)
    "current_over_limit_a",  # peak minus limit, signed (negative: the margin left)
    "voltage_saturation",  # fraction of periods with the voltage command on its limit
    "control_effort",  # mean of (|u_dq*| / u_max)^2
    "torque_ripple_nm",  # N m, RMS torque deviation over the last 20 % of the scenario
    "angle_error_rms_rad",  # electrical rad, RMS of the wrapped estimate error (0 on the exact sensor)
    "angle_chord_rms_rad",  # the same with each error e as the chord 2 sin(e/2) (smooth through +-pi)
)


@dataclasses.dataclass(frozen=True)
class ObjectiveWeights:
    """Weights of the cost ``sum_k w_k m_k + penalties``, averaged (or CVaR) over the batch.

    Defaults: minimise the speed ITAE; penalise overshoot, current above the limit and voltage
    saturation. The constraint penalties are linear (L1) beyond their thresholds, not quadratic: the kink
    at the threshold holds a tuned drive exactly at it, where a quadratic penalty, flat at zero, lets a
    small violation through (measured: 0.004 A over the limit, 0.003 % overshoot).
    """

    itae: float = 1.0
    iae: float = 0.0
    ise: float = 0.0
    overshoot: float = 0.1  # per % of overshoot beyond the allowance (linear)
    settling: float = 0.0  # per s (piecewise constant in the gains: informative, hardly a gradient)
    rms_current: float = 0.0  # per A
    control_effort: float = 0.0
    torque_ripple: float = 0.0  # per N m
    overshoot_allowed_pct: float = 0.0
    current_penalty: float = 1.0  # per A above the current limit (linear)
    voltage_saturation_penalty: float = 1.0  # per unit fraction of saturated time (soft count)
    aggregate: Literal["mean", "cvar"] = "mean"
    cvar_alpha: float = 0.8  # CVaR: mean of the worst (1 - alpha) share of scenarios
    # Widths of a quadratic zone that rounds the kink of the overshoot and current penalties, for
    # quasi-Newton methods ([`smoothed_penalty`][tuning.autotune.objectives.smoothed_penalty]); 0 = the exact
    # L1 penalties. The smoothed cost is what the optimiser follows; reports always use the exact one.
    overshoot_smoothing_pct: float = 0.0
    current_smoothing_a: float = 0.0
    # Per electrical rad of RMS angle-estimate error (sensorless drives; observer tuning), taken as the
    # RMS chord 2 sin(e/2) of the errors e
    # ([`scenario_metrics`][tuning.autotune.objectives.scenario_metrics]): the wrapped RMS for small errors.
    angle_error: float = 0.0
    # Stability-margin constraints (tuning.autotune.margin_constraints):
    # a phase-margin floor (deg) and a sensitivity-peak ceiling (1) of both loops, 0 = none, judged at the
    # operating point (mechanical rad/s, N m) on every plant of the batch; the penalty per degree short and
    # per 0.01 of peak over.
    min_phase_margin_deg: float = 0.0
    max_sensitivity_peak: float = 0.0
    margin_penalty: float = 0.1
    margin_speed_rad_s: float = 0.0
    margin_load_nm: float = 0.0

    def __post_init__(self):
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if f.name == "aggregate":
                if v not in ("mean", "cvar"):
                    raise ParameterError(f"aggregate must be 'mean' or 'cvar', got {v!r}.")
            elif not (isinstance(v, (int, float)) and v == v and v >= 0):
                raise ParameterError(f"objective weight {f.name} must be a number >= 0, got {v!r}.")
        if not 0 <= self.cvar_alpha < 1:
            raise ParameterError(f"cvar_alpha must lie in [0, 1), got {self.cvar_alpha}.")


def scenario_metrics(
    trace: Trace,
    duration_s,
    load_time_s,
    current_limit,
    u_max,
    soft_width: float = 0.005,
    observe_from_s=0.0,
    angle_modulo: float = 2.0 * np.pi,
) -> dict:
    """Figures of merit of one scenario's trace (see `METRIC_NAMES`), over its own duration; the
    angle error from ``observe_from_s`` (s) on, modulo ``angle_modulo`` (electrical rad: ``2 pi``, or
    ``pi`` for the injection estimators, whose error is wrapped to +-pi/2 and whose chord is
    ``sin(e)``, i.e. the chord of ``2e`` halved). The figures are those of
    [`pmsmjax.analysis`][pmsmjax.analysis]; here they get their windows."""
    t = trace.t
    active = (t < duration_s - 1e-12).astype(t.dtype)
    e = metrics.tracking_error(trace.speed_ref, trace.omega_m) * active

    # Overshoot and settling against the reference reached at the end of the pre-load window.
    pre = (t < load_time_s - 1e-12).astype(t.dtype)
    k_end = jnp.maximum(jnp.sum(pre).astype(jnp.int32) - 1, 0)
    w_final = trace.speed_ref[k_end]
    # the samples after the window count as 0: the signed value is floored at 0 when there are any
    excess = jnp.max(metrics.excess_over_reference(trace.omega_m, w_final) * pre)
    overshoot_signed = metrics.percent_of_reference(excess, w_final)
    settling = metrics.settling_time_to_reference(t, trace.omega_m, w_final, 0.02, pre)

    peak = metrics.peak_phase_current(trace.i_abc * active[:, None])
    tail = active * (t >= 0.8 * duration_s).astype(t.dtype)
    observed = active * (t >= observe_from_s - 1e-12).astype(t.dtype)
    angles = (trace.theta_e_est, trace.theta_e, observed, angle_modulo)
    return {
        "itae": metrics.itae(t, e),
        "iae": metrics.iae(t, e),
        "ise": metrics.ise(t, e),
        "overshoot_pct": jnp.maximum(overshoot_signed, 0.0),
        "overshoot_signed_pct": overshoot_signed,
        "settling_time_s": settling,
        "peak_current_a": peak,
        "rms_current_a": metrics.rms_phase_current(trace.i_abc, active),
        "current_excess_a": jnp.maximum(peak - current_limit, 0.0),
        "current_over_limit_a": peak - current_limit,
        "voltage_saturation": metrics.voltage_saturation(trace.u_dq_ref, u_max, active, soft_width),
        "control_effort": metrics.control_effort(trace.u_dq_ref, u_max, active),
        "torque_ripple_nm": metrics.ripple_rms_about_mean(trace.torque, tail),
        "angle_error_rms_rad": observer_errors.angle_error_rms(*angles),
        "angle_chord_rms_rad": observer_errors.angle_chord_rms(*angles),
    }


def smoothed_penalty(x, width: float):
    """``max(x, 0)`` with its kink rounded over ``[0, width]``: 0 for ``x <= 0``, ``x^2 / (2 width)``
    up to ``width``, ``x - width / 2`` beyond (continuous slope; exact on the feasible side, and never
    above the exact penalty). ``width = 0``: the exact ``max(x, 0)``."""
    if width == 0:
        return jnp.maximum(x, 0.0)
    inside = jnp.clip(x, 0.0, width)
    return inside * inside / (2.0 * width) + jnp.maximum(x - width, 0.0)


def scenario_cost(m: dict, w: ObjectiveWeights, smoothed: bool = False):
    """Weighted cost of one scenario's metrics ``m``; ``smoothed``: the penalties' kinks rounded with the
    widths of ``w`` ([`smoothed_penalty`][tuning.autotune.objectives.smoothed_penalty])."""
    over_x = m["overshoot_signed_pct"] - w.overshoot_allowed_pct
    current_x = m["current_over_limit_a"]
    over = smoothed_penalty(over_x, w.overshoot_smoothing_pct if smoothed else 0.0)
    # The current limit is a hard one: its rounded zone lies inside the limit (the smoothed penalty an
    # upper bound of the exact one), so the optimiser's optimum never sits past it; the overshoot's lies
    # past its allowance (a lower bound), a soft preference.
    current_width = w.current_smoothing_a if smoothed else 0.0
    current = smoothed_penalty(current_x + current_width, current_width)
    return (
        w.itae * m["itae"]
        + w.iae * m["iae"]
        + w.ise * m["ise"]
        + w.rms_current * m["rms_current_a"]
        + w.control_effort * m["control_effort"]
        + w.torque_ripple * m["torque_ripple_nm"]
        + w.settling * m["settling_time_s"]
        + w.overshoot * over
        + w.current_penalty * current
        + w.voltage_saturation_penalty * m["voltage_saturation"]
        + w.angle_error * m["angle_chord_rms_rad"]
    )


def aggregate(costs, w: ObjectiveWeights):
    """Batch cost: the mean, or the CVaR (mean of the worst ``1 - alpha`` share) of ``costs (B,)``."""
    if w.aggregate == "mean":
        return jnp.mean(costs)
    k = max(1, int(round((1.0 - w.cvar_alpha) * costs.shape[0])))
    return jnp.mean(jnp.sort(costs)[-k:])


#: The plant-scale names that scale a warm motor's thermal network (its initial and ambient temperature, K).
THERMAL_SCALED = ("initial_k", "ambient_k")


def batch_metrics(drive: Drive, batch: ScenarioBatch) -> dict:
    """Metrics of every scenario of ``batch`` run on ``drive``: a dict of ``(B,)`` arrays."""
    limit = drive.controller.current_limit

    def one(scenario, duration, t_load, scale, speed0, theta0, observe_from):
        plant = scaled_plant(drive, scale)
        start = None if speed0 is None else start_at_speed(plant, speed0, theta0)
        trace = pmsmjax.simulate(plant, scenario, initial_state=start)
        observe_from = 0.0 if observe_from is None else observe_from
        return scenario_metrics(
            trace,
            duration,
            t_load,
            limit,
            plant.modulator.linear_limit(plant.bridge.u_dc),  # the scenario's own DC link
            observe_from_s=observe_from,
            angle_modulo=batch.angle_modulo,
        )

    return jax.vmap(one)(
        batch.scenarios,
        batch.duration_s,
        batch.load_time_s,
        batch.plant_scale,
        batch.initial_speed_m,
        batch.initial_theta_e,
        batch.observe_from_s,
    )


def scaled_plant(drive: Drive, scale: dict) -> Drive:
    """``drive`` with a batch row's plant factors ``scale`` (``{name: factor}``, see
    [`ScenarioBatch`][tuning.autotune.scenario_batches.ScenarioBatch]): the motor's parameters, a warm motor's
    temperatures, the DC link and the current sensors' errors."""
    plant = drive
    names = [f"machine.motor.{n}" for n in scale if n not in ("u_dc_v",) + THERMAL_SCALED + SENSOR_SPREADS]
    names += [f"thermal.{n}" for n in scale if n in THERMAL_SCALED]  # a warm motor's temperatures, K
    if names:
        plant = set_leaves(plant, names, [get_leaf(drive, n) * scale[n.rsplit(".", 1)[1]] for n in names])
    if "u_dc_v" in scale:  # the DC link the bridge applies and the controller measures
        plant = set_leaves(plant, ["bridge.u_dc"], [drive.bridge.u_dc * scale["u_dc_v"]])
    if "current_offset_a" in scale or "current_gain" in scale:  # the sensors the controller reads
        k = drive.current_sensor.offset_a.shape[0]
        offset = drive.current_sensor.offset_a + scale.get("current_offset_a", jnp.zeros(3))[:k]
        gain = drive.current_sensor.gain * scale.get("current_gain", jnp.ones(3))[:k]
        plant = set_leaves(plant, ["current_sensor.offset_a", "current_sensor.gain"], [offset, gain])
    return plant


def _with_margins(cost, drive: Drive, batch: ScenarioBatch, weights: ObjectiveWeights):
    """``cost`` plus the margin constraints' penalty when ``weights`` set any."""
    from tuning.autotune import margin_constraints

    if not margin_constraints.constrained(weights):
        return cost
    return cost + margin_constraints.margin_penalty(drive, batch, weights, scaled_plant)


def start_at_speed(drive: Drive, speed_m, theta_e):
    """The drive's state at mechanical speed ``speed_m`` (rad/s) and electrical angle ``theta_e`` (rad),
    zero currents, with the speed loop in its no-load steady state
    ([`steady_state`][pmsmjax.controllers.base.AbstractSpeedController.steady_state]): the speed PI's integral
    holds its active-damping term ``B_a w`` (from a zero integral the damping term alone would brake the
    machine, measured 260 r/min of dip from 694 r/min on the book drive); other loops start from their
    ``init``."""
    state = drive.init(speed_m=speed_m, theta_e=theta_e)
    speed_state = drive.controller.speed.steady_state(state.controller.speed, speed_m)
    return set_leaves(state, ["controller.speed"], [speed_state])


def batch_cost(drive: Drive, batch: ScenarioBatch, weights: ObjectiveWeights):
    """``(cost, per_scenario_costs (B,), metrics)`` of ``drive`` on ``batch`` (exact penalties)."""
    m = batch_metrics(drive, batch)
    costs = jax.vmap(lambda mm: scenario_cost(mm, weights))(m)
    return _with_margins(aggregate(costs, weights), drive, batch, weights), costs, m


def smoothed_batch_cost(drive: Drive, batch: ScenarioBatch, weights: ObjectiveWeights):
    """``(smoothed cost, exact cost)``: the cost with the penalties' kinks rounded (the widths in
    ``weights``; the two coincide when both widths are 0) and the exact one, from one batch run."""
    m = batch_metrics(drive, batch)
    exact = aggregate(jax.vmap(lambda mm: scenario_cost(mm, weights))(m), weights)
    smooth = aggregate(jax.vmap(lambda mm: scenario_cost(mm, weights, smoothed=True))(m), weights)
    penalty = _with_margins(0.0, drive, batch, weights)
    return smooth + penalty, exact + penalty
