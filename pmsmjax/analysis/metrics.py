"""Figures of merit of drive responses, as jnp functions of sampled signals.

All take uniformly sampled signals (``t (N,)`` s). Integral criteria (ITAE, IAE, ISE) and RMS values are
differentiable; times and extrema (rise, settling, overshoot, dip) are differentiable almost everywhere
(crossings are linearly interpolated between samples, so they move smoothly with the signal).
Quantities that are undefined for a given signal (never rises, never settles) are NaN.
"""

import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.checks.validation import ParameterError
from pmsmjax.frames.three_phase import dq_to_abc


def _dt(t: Array) -> Array:
    return t[1] - t[0]


def itae(t: Array, error: Array) -> Array:
    """Integral of time-weighted absolute error, ``sum t |e| dt`` (units of e times s^2)."""
    return jnp.sum(t * jnp.abs(error), axis=-1) * _dt(t)


def iae(t: Array, error: Array) -> Array:
    """Integral of absolute error, ``sum |e| dt``."""
    return jnp.sum(jnp.abs(error), axis=-1) * _dt(t)


def ise(t: Array, error: Array) -> Array:
    """Integral of squared error, ``sum e^2 dt``."""
    return jnp.sum(error * error, axis=-1) * _dt(t)


def _normalised(y, y_start, y_final):
    return (y - y_start) / (y_final - y_start)


def _first_crossing(t, z, level):
    """Time at which ``z`` first reaches ``level`` (linear interpolation); NaN if it never does."""
    above = z >= level
    i = jnp.argmax(above)
    i0 = jnp.maximum(i - 1, 0)
    dz = z[i] - z[i0]
    frac = jnp.where(dz > 0, (level - z[i0]) / jnp.where(dz > 0, dz, 1.0), 0.0)
    t_cross = jnp.where(i > 0, t[i0] + frac * (t[i] - t[i0]), t[0])
    return jnp.where(jnp.any(above), t_cross, jnp.nan)


def rise_time(t: Array, y: Array, y_start, y_final, low: float = 0.1, high: float = 0.9) -> Array:
    """``low``-``high`` rise time (s) of a step response from ``y_start`` to ``y_final`` (either sign)."""
    z = _normalised(y, y_start, y_final)
    return _first_crossing(t, z, high) - _first_crossing(t, z, low)


def overshoot(y: Array, y_start, y_final) -> Array:
    """Peak overshoot beyond ``y_final``, percent of the step size (0 when there is none)."""
    z = _normalised(y, y_start, y_final)
    return 100.0 * jnp.maximum(jnp.max(z) - 1.0, 0.0)


def settling_time(t: Array, y: Array, y_start, y_final, band: float = 0.02) -> Array:
    """Time (s, from ``t[0]``) after which ``y`` stays within ``band`` of the step; NaN if never."""
    z = _normalised(y, y_start, y_final)
    outside = jnp.abs(z - 1.0) > band
    n = t.shape[0]
    last_outside = n - 1 - jnp.argmax(outside[::-1])
    settled_at = jnp.where(jnp.any(outside), t[jnp.minimum(last_outside + 1, n - 1)], t[0]) - t[0]
    return jnp.where(outside[-1], jnp.nan, settled_at)


def steady_state_error(y: Array, reference: Array, window: int) -> Array:
    """Mean of ``reference - y`` over the last ``window`` samples."""
    return jnp.mean(reference[..., -window:] - y[..., -window:], axis=-1)


def disturbance_dip(t: Array, y: Array, t_event: float, y_nominal, band: float) -> tuple[Array, Array]:
    """Response to a disturbance (load step) at ``t_event``.

    **Returns:** ``(dip, recovery_time)``: the largest drop of ``y`` below ``y_nominal`` after the event
    (same units as y), and the time (s, from the event) after which ``y`` stays within ``band`` (same
    units) of ``y_nominal``; NaN if it does not recover.
    """
    after = t >= t_event
    dip = jnp.max(jnp.where(after, y_nominal - y, -jnp.inf))
    outside = after & (jnp.abs(y - y_nominal) > band)
    n = t.shape[0]
    last_outside = n - 1 - jnp.argmax(outside[::-1])
    recovered_at = jnp.where(jnp.any(outside), t[jnp.minimum(last_outside + 1, n - 1)], t_event)
    return dip, jnp.where(outside[-1], jnp.nan, recovered_at - t_event)


def peak_phase_current(i_abc: Array) -> Array:
    """Largest absolute phase current (A) over ``i_abc (N, 3)``."""
    return jnp.max(jnp.abs(i_abc), axis=(-2, -1))


def rms_phase_current(i_abc: Array) -> Array:
    """RMS phase current (A) over the record, averaged over the three phases."""
    return jnp.sqrt(jnp.mean(i_abc * i_abc, axis=(-2, -1)))


def switching_frequency_hz(duties: Array, Ts: float) -> Array:
    """Mean switching frequency of the legs, Hz, comparable with a PWM carrier frequency.

    ``duties (N, n)`` are the legs' duties over ``N`` periods of ``Ts`` s: centre-aligned pulses (a leg
    with ``0 < d < 1`` switches on and off once each in its period, and is low at both period ends unless
    ``d = 1``) or switch states held over the period (0 or 1: a leg switches only where its state
    changes between periods). Transitions per leg per second, halved: one on-off pair is one switching
    period, so a carrier-based PWM at 10 kHz reads 10 kHz.
    """
    inside = 2.0 * jnp.sum((duties > 0.0) & (duties < 1.0), axis=(-2, -1))
    high = duties >= 1.0
    boundary = jnp.sum(high[..., 1:, :] != high[..., :-1, :], axis=(-2, -1))
    n_periods, n_legs = duties.shape[-2], duties.shape[-1]
    return (inside + boundary) / (2.0 * n_legs * n_periods * Ts)


def ripple_about_moving_mean(y: Array, window: int) -> Array:
    """Deviation of ``y (..., N)`` from its centred ``window``-sample moving mean: ``(..., N - window + 1)``.

    ``window`` (static int, odd for exact centring) should span several periods of the ripple and be short
    beside the slow trends it removes: a 101-sample window at 10 kHz (10 ms) spans four periods of the
    420 Hz sign-law chattering of the book SMC drive, and leaves of a 20 ms exponential decay a residual of
    ``sinh(W/2 tau)/(W/2 tau) - 1`` = 1 % of its local value (W = 10 ms, tau = 20 ms). The mean is a
    difference of cumulative sums of ``y - mean(y)`` (centred first, so float32 records of large offsets
    keep their precision).
    """
    n = y.shape[-1]
    if not isinstance(window, int) or not 1 <= window <= n:
        raise ParameterError(f"window must be an int in [1, {n}] samples, got {window!r}.")
    z = y - jnp.mean(y, axis=-1, keepdims=True)
    cs = jnp.cumsum(z, axis=-1)
    cs = jnp.concatenate([jnp.zeros(cs.shape[:-1] + (1,), cs.dtype), cs], axis=-1)
    moving_mean = (cs[..., window:] - cs[..., :-window]) / window
    half = (window - 1) // 2
    return z[..., half : half + n - window + 1] - moving_mean


def current_ripple_rms_a(i: Array, window: int) -> Array:
    """RMS (A) of a current (e.g. the speed loop's ``i_q*``) about its moving mean: the chattering metric.

    `i`: ``(..., N)`` samples, A, taken in steady state (the caller slices the window); `window`: moving
    mean length in samples (see :func:`ripple_about_moving_mean`).
    """
    dev = ripple_about_moving_mean(i, window)
    return jnp.sqrt(jnp.mean(dev * dev, axis=-1))


def current_ripple_peak_to_peak_a(i: Array, window: int) -> Array:
    """Peak-to-peak (A) of a current about its moving mean (see :func:`current_ripple_rms_a`)."""
    dev = ripple_about_moving_mean(i, window)
    return jnp.max(dev, axis=-1) - jnp.min(dev, axis=-1)


# --- current tracking of switching controllers (hysteresis current control, table DTC) --------------------


def reference_phase_currents(i_dq_ref: Array, theta_e_est: Array) -> Array:
    """``(N, 3)`` reference phase currents, A, from ``i_dq_ref (N, 2)`` A and the controller's
    (estimated) electrical angle ``theta_e_est (N,)`` rad: what a hysteresis controller compares with.

    From a trace: ``reference_phase_currents(trace.i_dq_ref, trace.theta_e_est)``.
    """
    return dq_to_abc(i_dq_ref, theta_e_est)


def current_error_rms_a(i_abc: Array, i_abc_ref: Array) -> Array:
    """RMS of the phase-current error ``i_abc - i_abc_ref`` (A) over the record and the phases.

    ``i_abc, i_abc_ref (N, 3)`` A; pass a steady-state window (e.g. ``trace[k0:]``). It includes any mean
    tracking error as well as the ripple (hysteresis control has almost none). With switch states held
    between samples the current is nearly linear between samples, so its extremes lie on the samples
    and sampled records resolve the ripple.
    """
    err = i_abc - i_abc_ref
    return jnp.sqrt(jnp.mean(err * err, axis=(-2, -1)))


def current_error_peak_a(i_abc: Array, i_abc_ref: Array) -> Array:
    """Largest absolute phase-current error ``|i_abc - i_abc_ref|`` (A) over the record and the phases."""
    return jnp.max(jnp.abs(i_abc - i_abc_ref), axis=(-2, -1))
