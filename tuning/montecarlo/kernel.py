"""One closed-loop run reduced to its figures of merit while it runs (the Monte Carlo kernel).

A Monte Carlo study needs a handful of numbers per run, not a full-rate trace: the metrics are
accumulated inside the scan (running ITAE, running maxima, the last period outside the settling band)
and only every ``decimate``-th period's speed and q-axis current are kept for the fan chart. On XLA:CPU
every per-period scan output is a separate write that costs about as much as a fair part of the drive
step, so this is what makes 10,000 runs of 4000 periods affordable.

The per-period terms are those of [`pmsmjax.analysis.metrics`][pmsmjax.analysis.metrics] and
[`pmsmjax.analysis.observer_errors`][pmsmjax.analysis.observer_errors]; this module only sums them or keeps
their maximum over the periods (tests/tuning/test_montecarlo.py and tests/studies/test_observer_study.py check
the results against the full-record figures of a trace from [`pmsmjax.simulate`][pmsmjax.simulate.simulate]):

- ``itae``: sum of [`itae_term`][pmsmjax.analysis.metrics.itae_term] ``t_k |w*_k - w_k|`` times ``Ts``, rad s
  (speed error in rad/s, whole run).
- ``overshoot_pct``: largest [`excess_over_reference`][pmsmjax.analysis.metrics.excess_over_reference] over
  the periods before the load step, each in
  [`percent_of_reference`][pmsmjax.analysis.metrics.percent_of_reference], floored at 0.
- ``settling_time_s``: start of the period after the last one before the load step that is
  [`outside_reference_band`][pmsmjax.analysis.metrics.outside_reference_band] (``settle_band``, a fraction of
  the reference); censored at the load step time when the speed has not settled by then
  ([`settling_time_to_reference`][pmsmjax.analysis.metrics.settling_time_to_reference]).
- ``dip_rpm``: largest [`tracking_error`][pmsmjax.analysis.metrics.tracking_error] ``w* - w`` after the load
  step, r/min.
- ``peak_current_a``: largest [`peak_phase_current`][pmsmjax.analysis.metrics.peak_phase_current] of the
  periods, A.
- ``final_error_rpm``: mean tracking error over the last ``tail_fraction`` of the run, r/min
  ([`steady_state_error`][pmsmjax.analysis.metrics.steady_state_error]).
- ``finite``: 1.0 if every sampled state stayed finite, else 0.0 (a run that diverged).

With an observer in the drive (``drive.records_estimate``), also
[`OBSERVER_METRICS`][tuning.montecarlo.kernel.OBSERVER_METRICS], defined as in
[`pmsmjax.analysis.observer_errors.observer_errors`][pmsmjax.analysis.observer_errors.observer_errors]
(periods from ``converged_after_s`` on):

- ``angle_error_rms_deg``, ``angle_error_max_deg``: RMS and largest ``|angle_error|``, electrical degrees;
- ``speed_error_rms_rpm``: RMS of ``omega_est - omega``, r/min;
- ``lock_lost``: 1.0 if a run of [`out_of_lock`][pmsmjax.analysis.observer_errors.out_of_lock] periods lasted
  longer than ``LOCK_WINDOW_S`` ([`lock_lost`][pmsmjax.analysis.observer_errors.lock_lost]), else 0.0.
"""

import equinox as eqx
import jax
import jax.numpy as jnp

from pmsmjax.analysis import metrics
from pmsmjax.analysis import observer_errors as om
from pmsmjax.drive import Drive
from pmsmjax.frames.three_phase import dq_to_abc
from pmsmjax.scenarios import Scenario
from pmsmjax.simulate import period_inputs
from pmsmjax.units import rad_s_to_rpm

METRICS = (
    "itae",
    "overshoot_pct",
    "settling_time_s",
    "dip_rpm",
    "peak_current_a",
    "final_error_rpm",
)
#: The observer's figures, kept when the drive has an observer (see the module docstring).
OBSERVER_METRICS = ("angle_error_rms_deg", "angle_error_max_deg", "speed_error_rms_rpm", "lock_lost")
#: Units of `METRICS` and [`OBSERVER_METRICS`][tuning.montecarlo.kernel.OBSERVER_METRICS], for tables and
#: figure labels.
UNITS = {
    "angle_error_rms_deg": "el. deg",
    "angle_error_max_deg": "el. deg",
    "speed_error_rms_rpm": "r/min",
    "lock_lost": "-",
    "itae": "rad s",
    "overshoot_pct": "%",
    "settling_time_s": "s",
    "dip_rpm": "r/min",
    "peak_current_a": "A",
    "final_error_rpm": "r/min",
}


class Accumulators(eqx.Module):
    """Running figures of merit carried through the scan (scalars)."""

    itae: jax.Array  # sum of t |e| (rad/s s), times Ts at the end
    excess: jax.Array  # largest excess over the reference before the load step, % of |w*|
    last_outside: jax.Array  # int32 index of the last pre-load period outside the band, -1 if none
    dip: jax.Array  # largest w* - w after the load step, rad/s
    peak: jax.Array  # largest |phase current|, A
    tail_error: jax.Array  # sum of w* - w over the tail window, rad/s
    finite: jax.Array  # bool, every sampled state finite so far
    observer: "ObserverAccumulators | None"  # None without an observer


class ObserverAccumulators(eqx.Module):
    """Running observer figures after convergence (scalars)."""

    angle_sq: jax.Array  # sum of e_theta^2, rad^2
    angle_max: jax.Array  # largest |e_theta|, rad
    speed_sq: jax.Array  # sum of (omega_est - omega)^2, (rad/s)^2
    run: jax.Array  # int32 length of the current out-of-lock run, periods
    longest: jax.Array  # int32 longest out-of-lock run, periods


def _init(dtype, observer: bool) -> Accumulators:
    zero = jnp.zeros((), dtype)
    izero = jnp.zeros((), jnp.int32)
    return Accumulators(
        zero,
        jnp.asarray(-jnp.inf, dtype),
        jnp.asarray(-1, jnp.int32),
        jnp.asarray(-jnp.inf, dtype),
        zero,
        zero,
        jnp.asarray(True),
        ObserverAccumulators(zero, zero, zero, izero, izero) if observer else None,
    )


def _observer_update(acc: ObserverAccumulators, after, ms, estimate, speed_ref) -> ObserverAccumulators:
    """One period of the observer figures (``estimate``: ``(2,)`` angle rad, speed rad/s)."""
    e_theta = om.angle_error(estimate[0], ms.theta_e)
    e_speed = estimate[1] - ms.omega_m
    run = om.out_of_lock_run(acc.run, after & om.out_of_lock(e_theta, e_speed, speed_ref))
    return ObserverAccumulators(
        angle_sq=acc.angle_sq + jnp.where(after, e_theta**2, 0.0),
        angle_max=jnp.where(after, jnp.maximum(acc.angle_max, jnp.abs(e_theta)), acc.angle_max),
        speed_sq=acc.speed_sq + jnp.where(after, e_speed**2, 0.0),
        run=run,
        longest=jnp.maximum(acc.longest, run),
    )


def run_metrics(
    drive: Drive,
    scenario: Scenario,
    load_time_s,
    *,
    decimate: int = 40,
    settle_band: float = 0.02,
    tail_fraction: float = 0.1,
    converged_after_s: float = om.CONVERGED_AFTER_S,
) -> tuple[dict, dict]:
    """Simulate ``drive`` through ``scenario`` keeping only the figures of merit and a decimated record.

    **Arguments:**

    - `drive`, `scenario`: as for [`pmsmjax.simulate`][pmsmjax.simulate.simulate] (unbatched; ``jax.vmap`` for
      batches).
    - `load_time_s`: time of the load step, s (scalar, may be traced): splits the step and load windows.
    - `decimate` (static): keep the speed and current of every this many periods (must divide the count).
    - `settle_band`, `tail_fraction` (static): see the module docstring.
    - `converged_after_s` (static): the observer figures count periods from this time on, s.

    **Returns:** ``(metrics, record)``: a dict of scalars keyed by `METRICS` plus ``finite`` (and
    [`OBSERVER_METRICS`][tuning.montecarlo.kernel.OBSERVER_METRICS] when the drive has an observer), and a
    dict with ``speed_rpm`` and ``i_q_a``, each ``(N / decimate,)`` (the first period of every block).
    """
    Ts = drive.Ts
    xs = period_inputs(scenario, Ts)
    n = xs.speed_ref.shape[0]
    state = drive.init()
    dtype = state.machine.omega_m.dtype
    k_tail = int(round((1.0 - tail_fraction) * n))
    k_converged = int(round(converged_after_s / Ts))
    observed = drive.records_estimate
    load_time_s = jnp.asarray(load_time_s, dtype)
    machine = drive.machine
    if machine.n_phases == 3:  # as the three-phase kernel always computed it
        phase_currents = lambda ms: dq_to_abc(machine.currents_dq(ms), ms.theta_e)
    else:
        phase_currents = machine.phase_currents

    def period(carry, k_x):
        s, acc = carry
        k, x = k_x
        ms = s.machine
        t = k.astype(dtype) * Ts
        w, ref = ms.omega_m, x.speed_ref
        e = metrics.tracking_error(ref, w)
        i_dq = drive.machine.currents_dq(ms)
        pre = t < load_time_s
        excess = metrics.percent_of_reference(metrics.excess_over_reference(w, ref), ref)
        outside = pre & metrics.outside_reference_band(w, ref, settle_band)
        finite = jnp.isfinite(w) & jnp.all(jnp.isfinite(ms.currents))
        s, rec = drive.step(s, x)
        obs = None
        if observed:
            obs = _observer_update(acc.observer, k >= k_converged, ms, rec.estimate, ref)
        acc = Accumulators(
            itae=acc.itae + metrics.itae_term(t, e),
            excess=jnp.where(pre, jnp.maximum(acc.excess, excess), acc.excess),
            last_outside=jnp.where(outside, k, acc.last_outside),
            dip=jnp.where(pre, acc.dip, jnp.maximum(acc.dip, e)),
            peak=jnp.maximum(acc.peak, metrics.peak_phase_current(phase_currents(ms)[None])),
            tail_error=acc.tail_error + jnp.where(k >= k_tail, e, 0.0),
            finite=acc.finite & finite,
            observer=obs,
        )
        return (s, acc), (w, i_dq[1])

    ks = jnp.arange(n, dtype=jnp.int32)
    blocks = jax.tree.map(lambda a: a.reshape((-1, decimate) + a.shape[1:]), (ks, xs))

    def block(carry, kx_block):
        carry, recorded = period(carry, jax.tree.map(lambda a: a[0], kx_block))
        rest = jax.tree.map(lambda a: a[1:], kx_block)
        carry, _ = jax.lax.scan(lambda c, kx: (period(c, kx)[0], None), carry, rest)
        return carry, recorded

    (_, acc), (w_rec, iq_rec) = jax.lax.scan(block, (state, _init(dtype, observed)), blocks)
    n_pre = jnp.sum((ks.astype(dtype) * Ts < load_time_s).astype(jnp.int32))
    settle_index = jnp.minimum(acc.last_outside + 1, n_pre)
    figures = {
        "itae": acc.itae * Ts,
        "overshoot_pct": jnp.maximum(acc.excess, 0.0),
        "settling_time_s": settle_index.astype(dtype) * Ts,
        "dip_rpm": rad_s_to_rpm(acc.dip),
        "peak_current_a": acc.peak,
        "final_error_rpm": rad_s_to_rpm(acc.tail_error / (n - k_tail)),
        "finite": acc.finite.astype(dtype),
    }
    if observed:
        o, n_after = acc.observer, max(n - k_converged, 1)
        figures["angle_error_rms_deg"] = jnp.degrees(jnp.sqrt(o.angle_sq / n_after))
        figures["angle_error_max_deg"] = jnp.degrees(o.angle_max)
        figures["speed_error_rms_rpm"] = rad_s_to_rpm(jnp.sqrt(o.speed_sq / n_after))
        figures["lock_lost"] = om.lock_lost(o.longest.astype(dtype), Ts).astype(dtype)
    return figures, {"speed_rpm": rad_s_to_rpm(w_rec), "i_q_a": iq_rec}


__all__ = ["run_metrics", "METRICS", "OBSERVER_METRICS", "UNITS"]
