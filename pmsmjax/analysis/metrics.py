"""Figures of merit of drive responses, as functions of sampled signals: JAX arrays in, JAX out (traceable,
differentiable); NumPy arrays in, NumPy out (post-processing of a recorded run, nothing to compile).

All take uniformly sampled signals (``t (N,)`` s). Integral criteria (ITAE, IAE, ISE) and RMS values are
differentiable; times and extrema (rise, settling, overshoot, dip) are differentiable almost everywhere
(crossings are linearly interpolated between samples, so they move smoothly with the signal).
Quantities that are undefined for a given signal (never rises, never settles) are NaN.

Step figures come in two families:

- **of a step response** ([`rise_time`][pmsmjax.analysis.metrics.rise_time],
  [`overshoot`][pmsmjax.analysis.metrics.overshoot],
  [`settling_time`][pmsmjax.analysis.metrics.settling_time]): relative to the step from ``y_start`` to
  ``y_final``, as read off one step
  ([`pmsmjax.analysis.speed_step_summary`][pmsmjax.analysis.speed_step_summary]);
- **against the reference** ([`excess_over_reference`][pmsmjax.analysis.metrics.excess_over_reference],
  [`settling_time_to_reference`][pmsmjax.analysis.metrics.settling_time_to_reference]): relative to the
  reference's magnitude sample by sample, so they apply to any scenario (reversals, ramps) and to one period
  at a time ([`tuning.autotune.objectives`][tuning.autotune.objectives],
  [`tuning.montecarlo.kernel`][tuning.montecarlo.kernel]).

For a step from rest the two coincide. Figures that a scan accumulates period by period
([`tuning.montecarlo.kernel`][tuning.montecarlo.kernel]) use the per-sample terms defined here
([`tracking_error`][pmsmjax.analysis.metrics.tracking_error],
[`itae_term`][pmsmjax.analysis.metrics.itae_term],
[`excess_over_reference`][pmsmjax.analysis.metrics.excess_over_reference],
[`outside_reference_band`][pmsmjax.analysis.metrics.outside_reference_band],
[`peak_phase_current`][pmsmjax.analysis.metrics.peak_phase_current] of one period) and sum them or keep their
maximum.

``active`` arguments are ``(N,)`` weights, 1.0 for the samples that count and 0.0 for the others (a
scenario's own duration inside a batch's common horizon): traced, so windows can differ across a ``vmap``.
"""

import jax
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.analysis.array_namespace import namespace as _namespace
from pmsmjax.analysis.current_ripple import (  # the current figures are metrics too: one import for users
    current_error_peak_a,
    current_error_rms_a,
    current_ripple_peak_to_peak_a,
    current_ripple_rms_a,
    reference_phase_currents,
    ripple_about_moving_mean,
)

__all__ = [
    "REFERENCE_FLOOR",
    "tracking_error",
    "itae_term",
    "itae",
    "iae",
    "ise",
    "first_sample_after_last",
    "rise_time",
    "overshoot",
    "settling_time",
    "excess_over_reference",
    "percent_of_reference",
    "outside_reference_band",
    "settling_time_to_reference",
    "steady_state_error",
    "disturbance_dip",
    "peak_phase_current",
    "rms_phase_current",
    "voltage_use",
    "voltage_saturation",
    "control_effort",
    "ripple_rms_about_mean",
    "switching_frequency_hz",
    "ripple_about_moving_mean",
    "current_ripple_rms_a",
    "current_ripple_peak_to_peak_a",
    "reference_phase_currents",
    "current_error_rms_a",
    "current_error_peak_a",
]

#: Floor of ``|reference|`` in the figures against the reference (units of the reference), so that a
#: zero reference gives finite numbers.
REFERENCE_FLOOR = 1e-6


def _dt(t: Array) -> Array:
    return t[1] - t[0]


def tracking_error(reference: Array, y: Array) -> Array:
    """``reference - y``: positive while ``y`` falls short of a positive reference.

    The error of every integral criterion, dip and steady-state figure here.

    Args:
        reference: The reference.
        y: The response, in the reference's units.

    Returns:
        The error, in the units of ``y``.
    """
    return reference - y


def itae_term(t: Array, error: Array) -> Array:
    """The per-sample term of ITAE, ``t |e|``; [`itae`][pmsmjax.analysis.metrics.itae] is its sum times
    ``dt``.

    Args:
        t: Sample times, s.
        error: The error ([`tracking_error`][pmsmjax.analysis.metrics.tracking_error]).

    Returns:
        ``t |e|``, units of e times s.
    """
    xp = _namespace(t, error)
    return t * xp.abs(error)


def itae(t: Array, error: Array) -> Array:
    """Integral of time-weighted absolute error, ``sum t |e| dt``.

    Args:
        t: ``(..., N)`` sample times, s (uniformly spaced).
        error: ``(..., N)`` error ([`tracking_error`][pmsmjax.analysis.metrics.tracking_error]).

    Returns:
        ITAE, units of e times s^2.
    """
    xp = _namespace(t, error)
    return xp.sum(itae_term(t, error), axis=-1) * _dt(t)


def iae(t: Array, error: Array) -> Array:
    """Integral of absolute error, ``sum |e| dt``.

    Args:
        t: ``(..., N)`` sample times, s (uniformly spaced).
        error: ``(..., N)`` error.

    Returns:
        IAE, units of e times s.
    """
    xp = _namespace(t, error)
    return xp.sum(xp.abs(error), axis=-1) * _dt(t)


def ise(t: Array, error: Array) -> Array:
    """Integral of squared error, ``sum e^2 dt``.

    Args:
        t: ``(..., N)`` sample times, s (uniformly spaced).
        error: ``(..., N)`` error.

    Returns:
        ISE, units of e squared times s.
    """
    xp = _namespace(t, error)
    return xp.sum(error * error, axis=-1) * _dt(t)


def _normalised(y, y_start, y_final):
    return (y - y_start) / (y_final - y_start)


def _first_crossing(t, z, level):
    """Time at which ``z`` first reaches ``level`` (linear interpolation); NaN if it never does."""
    xp = _namespace(t, z, level)
    above = z >= level
    i = xp.argmax(above)
    i0 = xp.maximum(i - 1, 0)
    dz = z[i] - z[i0]
    frac = xp.where(dz > 0, (level - z[i0]) / xp.where(dz > 0, dz, 1.0), 0.0)
    t_cross = xp.where(i > 0, t[i0] + frac * (t[i] - t[i0]), t[0])
    return xp.where(xp.any(above), t_cross, xp.nan)


def first_sample_after_last(flags: Array) -> Array:
    """Index of the first sample after the last ``True``: where a settling or recovery time starts to hold.

    Args:
        flags: ``(..., N)`` booleans.

    Returns:
        The index: 0 when none is set, ``N`` when the last sample is set.
    """
    xp = _namespace(flags)
    n = flags.shape[-1]
    return xp.max(xp.where(flags, xp.arange(1, n + 1), 0), axis=-1)


def rise_time(t: Array, y: Array, y_start, y_final, low: float = 0.1, high: float = 0.9) -> Array:
    """``low``-``high`` rise time of a step response from ``y_start`` to ``y_final`` (either sign).

    Args:
        t: ``(N,)`` sample times, s.
        y: ``(N,)`` response.
        y_start: Value before the step.
        y_final: Value the step goes to.
        low: Lower fraction of the step.
        high: Upper fraction of the step.

    Returns:
        The rise time, s.
    """
    z = _normalised(y, y_start, y_final)
    return _first_crossing(t, z, high) - _first_crossing(t, z, low)


def overshoot(y: Array, y_start, y_final) -> Array:
    """Peak overshoot beyond ``y_final``, percent of the step size (0 when there is none).

    Args:
        y: ``(N,)`` response.
        y_start: Value before the step.
        y_final: Value the step goes to.
    """
    xp = _namespace(y, y_start, y_final)
    z = _normalised(y, y_start, y_final)
    return 100.0 * xp.maximum(xp.max(z) - 1.0, 0.0)


def settling_time(t: Array, y: Array, y_start, y_final, band: float = 0.02) -> Array:
    """Time after which ``y`` stays within ``band`` of the step.

    Args:
        t: ``(N,)`` sample times, s.
        y: ``(N,)`` response.
        y_start: Value before the step.
        y_final: Value the step goes to.
        band: Band as a fraction of the step size.

    Returns:
        The settling time, s, from ``t[0]``; NaN if never.
    """
    xp = _namespace(t, y, y_start, y_final, band)
    z = _normalised(y, y_start, y_final)
    n = t.shape[0]
    k = first_sample_after_last(xp.abs(z - 1.0) > band)
    return xp.where(k == n, xp.nan, t[xp.minimum(k, n - 1)] - t[0])


def _reference_scale(reference):
    xp = _namespace(reference)
    return xp.maximum(xp.abs(reference), REFERENCE_FLOOR)


def excess_over_reference(y: Array, reference: Array) -> Array:
    """``sign(reference) (y - reference)``: how far ``y`` lies beyond the reference in its direction.

    Its largest value over a step's window, in
    [`percent_of_reference`][pmsmjax.analysis.metrics.percent_of_reference] and floored at 0, is the overshoot
    against the reference; for a step from rest it equals [`overshoot`][pmsmjax.analysis.metrics.overshoot].

    Args:
        y: Response, per sample.
        reference: Reference, same shape.

    Returns:
        The excess per sample, units of y (negative: short of the reference).
    """
    return jnp.sign(reference) * (y - reference)


def percent_of_reference(x: Array, reference: Array) -> Array:
    """``100 x / |reference|``, with ``|reference|`` floored at
    [`REFERENCE_FLOOR`][pmsmjax.analysis.metrics.REFERENCE_FLOOR].

    Args:
        x: A quantity in the reference's units.
        reference: The reference.
    """
    return 100.0 * x / _reference_scale(reference)


def outside_reference_band(y: Array, reference: Array, band: float) -> Array:
    """``True`` where ``|y - reference| > band |reference|`` (``|reference|`` floored at
    [`REFERENCE_FLOOR`][pmsmjax.analysis.metrics.REFERENCE_FLOOR]); per sample.

    Args:
        y: Response.
        reference: Reference, same shape.
        band: Band as a fraction of the reference.
    """
    xp = _namespace(y, reference, band)
    return xp.abs(y - reference) > band * _reference_scale(reference)


def settling_time_to_reference(t: Array, y: Array, reference: Array, band: float, active: Array) -> Array:
    """Time of the first sample after the last ``active`` one outside ``band`` of the reference
    ([`outside_reference_band`][pmsmjax.analysis.metrics.outside_reference_band]).

    Censored rather than NaN, so that it stays usable in a cost: a window that ends unsettled gives the time
    of the sample after it (the record's last sample when the window reaches the end).

    Args:
        t: ``(..., N)`` sample times, s.
        y: ``(..., N)`` response.
        reference: ``(..., N)`` reference.
        band: Band as a fraction of the reference.
        active: ``(..., N)`` booleans, the samples of the window.

    Returns:
        The settling time, s, from ``t[0]``; ``0`` when no sample is outside.
    """
    xp = _namespace(t, y, reference, band, active)
    k = first_sample_after_last(outside_reference_band(y, reference, band) & (active > 0))
    return t[xp.minimum(k, t.shape[-1] - 1)] - t[0]


def steady_state_error(y: Array, reference: Array, window: int) -> Array:
    """Mean [`tracking_error`][pmsmjax.analysis.metrics.tracking_error] ``reference - y`` over the last
    ``window`` samples.

    Args:
        y: ``(..., N)`` response.
        reference: ``(..., N)`` reference.
        window: Number of final samples.
    """
    xp = _namespace(y, reference, window)
    return xp.mean(tracking_error(reference[..., -window:], y[..., -window:]), axis=-1)


def disturbance_dip(t: Array, y: Array, t_event: float, y_nominal, band: float) -> tuple[Array, Array]:
    """Response to a disturbance (load step) at ``t_event``.

    Args:
        t: ``(N,)`` sample times, s.
        y: ``(N,)`` response.
        t_event: Time of the disturbance, s.
        y_nominal: Value ``y`` should hold.
        band: Recovery band, in the units of ``y``.

    Returns:
        ``(dip, recovery_time)``: the largest drop of ``y`` below ``y_nominal`` after the event (same units
        as y), and the time (s, from the event) after which ``y`` stays within ``band`` of ``y_nominal``;
        NaN if it does not recover.
    """
    xp = _namespace(t, y, t_event, y_nominal, band)
    after = t >= t_event
    dip = xp.max(xp.where(after, tracking_error(y_nominal, y), -xp.inf))
    n = t.shape[0]
    k = first_sample_after_last(after & (xp.abs(y - y_nominal) > band))
    recovered_at = xp.where(k > 0, t[xp.minimum(k, n - 1)], t_event)
    return dip, xp.where(k == n, xp.nan, recovered_at - t_event)


def peak_phase_current(i_abc: Array) -> Array:
    """Largest absolute phase current.

    Over a window: pass ``i_abc * active[:, None]``.

    Args:
        i_abc: ``(N, n_phases)`` phase currents, A (one period: ``(1, n_phases)``).

    Returns:
        The peak, A.
    """
    xp = _namespace(i_abc)
    return xp.max(xp.abs(i_abc), axis=(-2, -1))


def rms_phase_current(i_abc: Array, active: Array | None = None) -> Array:
    """RMS phase current over the record (or the ``active`` samples), averaged over the phases.

    Args:
        i_abc: ``(N, n_phases)`` phase currents, A.
        active: ``(N,)`` booleans, or ``None`` for all samples.

    Returns:
        The RMS current, A.
    """
    xp = _namespace(i_abc, active)
    if active is None:
        return xp.sqrt(xp.mean(i_abc * i_abc, axis=(-2, -1)))
    squares = xp.sum(i_abc * i_abc * active[..., None], axis=(-2, -1))
    return xp.sqrt(squares / (i_abc.shape[-1] * xp.sum(active, axis=-1)))


def voltage_use(u_dq_ref: Array, u_max) -> Array:
    """``|u_dq*| / u_max`` per sample.

    Args:
        u_dq_ref: ``(N, 2)`` voltage command, V.
        u_max: The modulator's linear limit, V.
    """
    xp = _namespace(u_dq_ref, u_max)
    return xp.sqrt(xp.sum(u_dq_ref**2, axis=-1) + 1e-12) / u_max


def voltage_saturation(u_dq_ref: Array, u_max, active: Array, soft_width: float = 0.005) -> Array:
    """Fraction of the ``active`` periods with the voltage command on its limit, counted softly (a
    sigmoid of [`voltage_use`][pmsmjax.analysis.metrics.voltage_use] about 0.999 of width ``soft_width``) so
    that it has a gradient.

    Args:
        u_dq_ref: ``(N, 2)`` voltage command, V.
        u_max: The modulator's linear limit, V.
        active: ``(N,)`` booleans, the periods counted.
        soft_width: Width of the sigmoid, in units of ``u_max``.
    """
    on_limit = jax.nn.sigmoid((voltage_use(u_dq_ref, u_max) - 0.999) / soft_width)
    return jnp.sum(on_limit * active) / jnp.sum(active)


def control_effort(u_dq_ref: Array, u_max, active: Array) -> Array:
    """Mean of ``(|u_dq*| / u_max)^2`` over the ``active`` periods
    ([`voltage_use`][pmsmjax.analysis.metrics.voltage_use]).

    Args:
        u_dq_ref: ``(N, 2)`` voltage command, V.
        u_max: The modulator's linear limit, V.
        active: ``(N,)`` booleans, the periods counted.
    """
    xp = _namespace(u_dq_ref, u_max, active)
    return xp.sum(voltage_use(u_dq_ref, u_max) ** 2 * active) / xp.sum(active)


def ripple_rms_about_mean(y: Array, active: Array) -> Array:
    """RMS deviation of ``y`` about its mean over the ``active`` samples (0 if none): the torque ripple of a
    steady window.

    Args:
        y: ``(N,)`` samples.
        active: ``(N,)`` booleans.

    Returns:
        The RMS deviation, units of y.
    """
    xp = _namespace(y, active)
    n = xp.maximum(xp.sum(active), 1.0)
    mean = xp.sum(y * active) / n
    return xp.sqrt(xp.sum((y - mean) ** 2 * active) / n)


def switching_frequency_hz(duties: Array, Ts: float) -> Array:
    """Mean switching frequency of the legs, comparable with a PWM carrier frequency.

    The duties are centre-aligned pulses (a leg with ``0 < d < 1`` switches on and off once each in its
    period, and is low at both period ends unless ``d = 1``) or switch states held over the period (0 or 1:
    a leg switches only where its state changes between periods). Transitions per leg per second, halved:
    one on-off pair is one switching period, so a carrier-based PWM at 10 kHz reads 10 kHz.

    Args:
        duties: ``(N, n)`` the legs' duties over ``N`` periods.
        Ts: The period, s.

    Returns:
        The frequency, Hz.
    """
    xp = _namespace(duties, Ts)
    inside = 2.0 * xp.sum((duties > 0.0) & (duties < 1.0), axis=(-2, -1))
    high = duties >= 1.0
    boundary = xp.sum(high[..., 1:, :] != high[..., :-1, :], axis=(-2, -1))
    n_periods, n_legs = duties.shape[-2], duties.shape[-1]
    return (inside + boundary) / (2.0 * n_legs * n_periods * Ts)
