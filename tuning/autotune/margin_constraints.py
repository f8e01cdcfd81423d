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

import jax
import jax.numpy as jnp

__all__ = ["constrained", "margin_penalty", "plant_margins"]


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
