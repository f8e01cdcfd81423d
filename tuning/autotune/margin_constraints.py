"""Stability-margin constraints in the tuning objective: a phase-margin floor and a sensitivity-peak ceiling,
judged on the drive linearised at one operating point for every plant of the batch.

For each plant draw of the batch (the scenarios' ``plant_scale``; the nominal plant without a spread), the
drive is linearised at the weights' operating point
([`pmsmjax.analysis.loop_linearisation.linearise_traced`][pmsmjax.analysis.loop_linearisation.linearise_traced])
and both loops' margins computed
([`pmsmjax.analysis.margins.loop_margins`][pmsmjax.analysis.margins.loop_margins]).
The penalty is ``margin_penalty`` per degree of phase margin below ``min_phase_margin_deg`` plus per 0.01 of
sensitivity peak above ``max_sensitivity_peak``, taken on the worst plant and the worse loop: a
constraint over
the whole spread, not on average. Linear beyond the threshold, like the objective's other constraints. The
margins are differentiable through the linearisation (its Jacobians, the Newton steps to the fixed point
and the
interpolated crossovers), so the gradient pushes back as soon as a plant crosses the threshold.
"""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from pmsmjax.spec.validation import ParameterError

__all__ = [
    "constrained",
    "margin_penalty",
    "plant_margins",
    "margin_operating_point",
    "margin_weights",
    "margins_report",
]


def constrained(weights) -> bool:
    """Whether ``weights`` ([`ObjectiveWeights`][tuning.autotune.objectives.ObjectiveWeights]) set a margin
    constraint."""
    return weights.min_phase_margin_deg > 0 or weights.max_sensitivity_peak > 0


def plant_margins(drive, batch, weights, plant_of) -> dict:
    """``{loop: LoopMargins with (B,) leaves}`` and ``"spectral_radius"``-free linearisations of each plant of
    ``batch`` at the weights' operating point; ``plant_of(drive, scale)`` builds a plant draw (the objective's
    own scaling)."""
    from pmsmjax.analysis.loop_linearisation import LOOPS, linearise_traced
    from pmsmjax.analysis.margins import loop_margins

    dtype = drive.machine.motor.R.dtype
    speed = jnp.asarray(weights.margin_speed_rad_s, dtype)
    load = jnp.asarray(weights.margin_load_nm, dtype)

    def one(scale):
        lin = linearise_traced(plant_of(drive, scale), speed, load)
        return {loop: loop_margins(lin, loop) for loop in LOOPS}

    if not batch.plant_scale:
        return jax.tree.map(lambda a: a[None], one({}))
    return jax.vmap(one)(batch.plant_scale)


def margin_penalty(drive, batch, weights, plant_of):
    """The constraint penalty (module docstring): cost units, 0 when every plant meets both constraints."""
    margins = plant_margins(drive, batch, weights, plant_of)
    total = jnp.zeros((), drive.machine.motor.R.dtype)
    for m in margins.values():
        if weights.min_phase_margin_deg > 0:
            pm = jnp.where(jnp.isfinite(m.phase_margin_deg), m.phase_margin_deg, 180.0)
            total = total + jnp.max(jnp.maximum(weights.min_phase_margin_deg - pm, 0.0))
        if weights.max_sensitivity_peak > 0:
            total = total + 100.0 * jnp.max(
                jnp.maximum(m.sensitivity_peak - weights.max_sensitivity_peak, 0.0)
            )
    return weights.margin_penalty * total


def margin_operating_point(spec) -> tuple[float, float]:
    """The operating point the margins are judged at: the middle of the drive file's ``[tuning]`` speed
    (rad/s,
    mechanical) and load (N m) ranges."""
    speed = float(np.mean(spec.tuning.speed_rpm)) * np.pi / 30.0
    return speed, float(np.mean(spec.tuning.load_nm))


def margin_weights(weights, spec, control, machine, estimator, min_pm, max_ms):
    """``weights`` with the margin constraints given (None: the weights' own, e.g. from a config's
    ``[weights]``) and, when any is set, the operating point; refused outside the linearisation's scope."""
    if min_pm is not None or max_ms is not None:
        weights = dataclasses.replace(
            weights,
            min_phase_margin_deg=weights.min_phase_margin_deg if min_pm is None else float(min_pm),
            max_sensitivity_peak=weights.max_sensitivity_peak if max_ms is None else float(max_ms),
        )
    if weights.min_phase_margin_deg <= 0 and weights.max_sensitivity_peak <= 0:
        return weights
    if estimator is not None or control != "pi" or machine != "three-phase":
        raise ParameterError(
            "--min-phase-margin-deg / --max-sensitivity-peak constrain the three-phase FOC's loops (control "
            "pi, no --estimator): drop them for this tuning."
        )
    if weights.max_sensitivity_peak and weights.max_sensitivity_peak <= 1.0:
        raise ParameterError(
            f"--max-sensitivity-peak {weights.max_sensitivity_peak:g} is not above 1 (|S| reaches 1 at "
            "high frequency on every loop): give e.g. 1.6 to 2."
        )
    if weights.min_phase_margin_deg >= 90.0:
        raise ParameterError(
            f"--min-phase-margin-deg {weights.min_phase_margin_deg:g} is not below 90 deg: give e.g. 30 "
            "to 60."
        )
    speed, load = margin_operating_point(spec)
    return dataclasses.replace(weights, margin_speed_rad_s=speed, margin_load_nm=load)


def margins_report(before, after, drawn, weights, spec, plant_of) -> dict:
    """result.json's ``margins``: both loops' margins at the operating point
    ([`margin_operating_point`][tuning.autotune.margin_constraints.margin_operating_point]) on the nominal
    plant before and after tuning, and the worst phase margin and sensitivity peak over the held-out plant
    draws ``drawn`` (None: no tolerances; ``plant_of(drive, scale)`` builds a draw); a drive or point outside
    the linearisation's scope is reported, not raised."""
    from pmsmjax.analysis.margins import drive_margins

    speed, load = margin_operating_point(spec)
    out = {"operating_point": {"speed_rad_s": speed, "load_nm": load}}
    if weights.min_phase_margin_deg > 0 or weights.max_sensitivity_peak > 0:
        out["constraints"] = {
            "min_phase_margin_deg": weights.min_phase_margin_deg or None,
            "max_sensitivity_peak": weights.max_sensitivity_peak or None,
        }
    point = dataclasses.replace(weights, margin_speed_rad_s=speed, margin_load_nm=load)
    try:
        for name, drive in (("before", before), ("after", after)):
            entry = {"nominal": drive_margins(drive, speed, load, "[tuning] ranges' middle")}
            if drawn is not None:
                m = jax.device_get(plant_margins(drive, drawn, point, plant_of))
                entry["worst_over_drawn_plants"] = {
                    loop: {
                        "phase_margin_deg": float(np.min(v.phase_margin_deg)),
                        "sensitivity_peak": float(np.max(v.sensitivity_peak)),
                    }
                    for loop, v in m.items()
                }
            out[name] = entry
    except ParameterError as err:
        out["skipped"] = str(err)
    return out
