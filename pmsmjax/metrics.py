"""Figures of merit of drive responses, as jnp functions of sampled signals.

All take uniformly sampled signals (``t (N,)`` s). Integral criteria (ITAE, IAE, ISE) and RMS values are
differentiable; times and extrema (rise, settling, overshoot, dip) are differentiable almost everywhere
(crossings are linearly interpolated between samples, so they move smoothly with the signal).
Quantities that are undefined for a given signal (never rises, never settles) are NaN.
"""

import jax.numpy as jnp

from ._types import Array
from .frames import dq_to_abc


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


# --- switching controllers (hysteresis current control, table DTC) ----------------------------------------


def mean_switching_frequency_hz(t: Array, switch_states: Array) -> Array:
    """Mean switching frequency, Hz: transitions per leg per second, divided by 2.

    ``switch_states (N, n)``: the leg states applied in each period (``trace.duties`` of an undecimated
    trace of a switching controller; a decimated trace misses transitions); ``t (N,)`` s. A transition
    is a change of a leg's state between consecutive periods, counted as ``|s[k+1] - s[k]|`` (the total
    variation, so a smooth surrogate's fractional states count fractionally). The halving makes it
    comparable with a PWM carrier frequency: a PWM leg switches on and off once per carrier period,
    i.e. two transitions per period.
    """
    transitions = jnp.sum(jnp.abs(jnp.diff(switch_states, axis=-2)), axis=(-2, -1))
    n_legs = switch_states.shape[-1]
    return transitions / (n_legs * (t[..., -1] - t[..., 0])) / 2.0


def reference_phase_currents(i_dq_ref: Array, theta_e_est: Array) -> Array:
    """``(N, 3)`` reference phase currents, A, from ``i_dq_ref (N, 2)`` A and the controller's
    (estimated) electrical angle ``theta_e_est (N,)`` rad: what a hysteresis controller compares with.

    From a trace: ``reference_phase_currents(trace.i_dq_ref, trace.theta_e_est)``.
    """
    return dq_to_abc(i_dq_ref, theta_e_est)


def current_ripple_rms_a(i_abc: Array, i_abc_ref: Array) -> Array:
    """RMS of the phase-current error ``i_abc - i_abc_ref`` (A) over the record and the phases.

    ``i_abc, i_abc_ref (N, 3)`` A; pass a steady-state window (e.g. ``trace[k0:]``). It includes any mean
    tracking error as well as the ripple (hysteresis control has almost none). With switch states held
    between samples the current is nearly linear between samples, so its extremes lie on the samples
    and sampled records resolve the ripple.
    """
    err = i_abc - i_abc_ref
    return jnp.sqrt(jnp.mean(err * err, axis=(-2, -1)))


def current_ripple_peak_a(i_abc: Array, i_abc_ref: Array) -> Array:
    """Largest absolute phase-current error ``|i_abc - i_abc_ref|`` (A) over the record and the phases."""
    return jnp.max(jnp.abs(i_abc - i_abc_ref), axis=(-2, -1))
