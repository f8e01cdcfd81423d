"""Figures of merit of a sensorless drive's observer (the book, ch. 5): angle and speed estimation
error, loss of lock, and whether a speed is held under load.

The definitions below serve every user, in three forms:

- **Per sample**, on NumPy or JAX arrays alike (traceable):
  [`angle_error`][pmsmjax.analysis.observer_errors.angle_error],
  [`out_of_lock`][pmsmjax.analysis.observer_errors.out_of_lock],
  [`out_of_lock_run`][pmsmjax.analysis.observer_errors.out_of_lock_run],
  [`lock_lost`][pmsmjax.analysis.observer_errors.lock_lost]. The Monte Carlo kernel
  ([`tuning.montecarlo.kernel`][tuning.montecarlo.kernel]) accumulates them period by period inside its scan
  (sums of squares, maxima, the run length).
- **Over a full record**, in NumPy: [`observer_errors`][pmsmjax.analysis.observer_errors.observer_errors]
  (``pmsmjax compare --estimator``) and [`speed_held`][pmsmjax.analysis.observer_errors.speed_held] in float64
  whatever the precision of the run, [`error_statistics`][pmsmjax.analysis.observer_errors.error_statistics]
  (``pmsmjax observe``) in that of its inputs.
- **Over a traced window**, in jnp and differentiable:
  [`angle_error_rms`][pmsmjax.analysis.observer_errors.angle_error_rms],
  [`angle_chord_rms`][pmsmjax.analysis.observer_errors.angle_chord_rms] (the tuning objectives,
  [`tuning.autotune.objectives`][tuning.autotune.objectives]).

Definitions:

- **Angle error** ``e_theta = wrap(theta_e_est - theta_e)``, electrical rad wrapped to [-pi, pi), at each
  period start (the sampling instant, where the observer's estimate and the plant's angle belong together).
- **Speed estimation error** ``omega_m_est - omega_m``, mechanical rad/s.
- **After convergence**: only periods starting at or after ``converged_after_s`` count (the I/f start-up's
  hand-over of the book drive ends at 26 ms;
  [`CONVERGED_AFTER_S`][pmsmjax.analysis.observer_errors.CONVERGED_AFTER_S] leaves the observer and the speed
  loop 24 ms more).
- **Loss of lock**: after convergence, a run of more than ``lock_window_s``
  ([`LOCK_WINDOW_S`][pmsmjax.analysis.observer_errors.LOCK_WINDOW_S], 10 ms: longer than any transient of a
  locked observer, shorter than the load-step recovery) consecutive periods that are each *out of lock*:
  ``|e_theta| > 90 deg el`` (the controller then produces torque of the wrong sign) or
  ``|omega_m_est - omega_m| > 0.5 |omega*| + 1 rad/s`` (half the reference; the 1 rad/s floor keeps a zero
  reference meaningful).
- **Modulo pi** (``modulo_pi=True``, the chapter 6 injection estimators, which find the d axis without
  its polarity): the angle error is ``wrap(2 e_theta) / 2`` in [-pi/2, pi/2), and out of lock by angle is
  ``|e_theta| > 45 deg el``
  ([`LOCK_ANGLE_MODULO_PI_RAD`][pmsmjax.analysis.observer_errors.LOCK_ANGLE_MODULO_PI_RAD]): the saliency
  error signal ``~ sin(2 e_theta)`` has its unstable equilibrium at 90 degrees, and half-way to it is the same
  margin the 90 degrees give a back-EMF observer, whose torque changes sign at 180.
- **Angle-only lock** (``speed_lock=False``, the fixed low-speed scenarios of ``compare --estimator``:
  standstill and the 60 r/min reversal under a load step): only the angle criterion counts. There the
  reference is (near) zero while the load step throws the rotor to ~360 r/min and back within 50 ms; the
  speed criterion's 1 rad/s floor then flags the estimate's lag behind that transient (with
  ``hfi-rotating``: up to 180 r/min for 50 ms while the angle error stayed within 11 deg el), which is
  no loss of lock.
- **Held** ([`speed_held`][pmsmjax.analysis.observer_errors.speed_held]): over a judging window,
  ``max |omega* - omega| <= 0.1 |omega*|`` and ``max |e_theta| <= 30 deg el``, and the run lost no lock.
- **Chord** ([`angle_chord_rms`][pmsmjax.analysis.observer_errors.angle_chord_rms]): each error ``e`` counted
  as ``2 sin(e/2)``, whose square ``2 - 2 cos e`` is ``e^2`` to within ``e^4/12`` and is periodic and smooth
  where the wrapped error jumps by a turn (a lost lock would otherwise put jumps into a cost an optimiser
  follows).
"""

import math

import jax.numpy as jnp
import numpy as np

from pmsmjax.analysis.metrics import tracking_error
from pmsmjax.frames.three_phase import wrap_angle
from pmsmjax.units import rad_s_to_rpm

#: Periods before this time (s) are not counted (I/f start and hand-over of the book drive, then 24 ms).
CONVERGED_AFTER_S = 0.05
#: A loss of lock is out-of-lock for longer than this (s).
LOCK_WINDOW_S = 0.01
#: Out of lock: angle error beyond this (electrical rad) ...
LOCK_ANGLE_RAD = math.pi / 2
#: ... or, scored modulo pi (injection without polarity), beyond this (electrical rad).
LOCK_ANGLE_MODULO_PI_RAD = math.pi / 4
#: ... or speed estimation error beyond this fraction of |omega*| plus `LOCK_SPEED_FLOOR_RAD_S`.
LOCK_SPEED_FRACTION = 0.5
LOCK_SPEED_FLOOR_RAD_S = 1.0
#: Held: speed error at most this fraction of |omega*| and angle error at most this (electrical rad).
HELD_SPEED_FRACTION = 0.1
HELD_ANGLE_RAD = math.radians(30.0)

# --- per sample (NumPy or JAX) ------------------------------------------------------------------------


def angle_error(theta_est, theta, period: float = 2.0 * math.pi):
    """``theta_est - theta`` wrapped to [-period/2, period/2).

    NumPy in, NumPy out in its precision; JAX in, JAX out. ``period`` ``pi``: the error of an estimate of
    the d axis without its polarity, ``wrap(2 (theta_est - theta)) / 2``.

    Args:
        theta_est: Estimated angle, rad.
        theta: True angle, rad (same shape).
        period: The period the error is wrapped to, rad.

    Returns:
        The error, rad.
    """
    m = 2.0 * math.pi / period
    if m == 1.0:
        return wrap_angle(theta_est - theta)
    return wrap_angle(m * (theta_est - theta)) / m


def angle_error_modulo_pi(theta_est, theta):
    """``wrap(2 (theta_est - theta)) / 2`` in
    [-pi/2, pi/2): [`angle_error`][pmsmjax.analysis.observer_errors.angle_error] with period pi.

    Args:
        theta_est: Estimated angle, rad.
        theta: True angle, rad.

    Returns:
        The error, rad.
    """
    return angle_error(theta_est, theta, math.pi)


def out_of_lock(e_theta, e_speed, speed_ref, modulo_pi: bool = False, speed_lock: bool = True):
    """Per-period out-of-lock flags (see the module docstring); NumPy or JAX.

    Args:
        e_theta: Angle error, rad.
        e_speed: Speed estimation error, rad/s (same shape).
        speed_ref: Speed reference, rad/s (same shape).
        modulo_pi: Judge the angle modulo pi.
        speed_lock: Judge the speed error too (else the angle alone).
    """
    limit = LOCK_SPEED_FRACTION * abs(speed_ref) + LOCK_SPEED_FLOOR_RAD_S
    angle_limit = LOCK_ANGLE_MODULO_PI_RAD if modulo_pi else LOCK_ANGLE_RAD
    out = abs(e_theta) > angle_limit
    return out | (abs(e_speed) > limit) if speed_lock else out


def out_of_lock_run(run, out):
    """Length of the current run of out-of-lock periods after one more period. A scan carries it from 0.

    Args:
        run: The run's length before the period, periods.
        out: The period's out-of-lock flag.

    Returns:
        ``run + 1``, or 0 when that period is in lock.
    """
    return (run + 1) * out


def lock_lost(longest_run_periods, Ts: float):
    """Whether a run of out-of-lock periods loses lock (lasts longer than
    [`LOCK_WINDOW_S`][pmsmjax.analysis.observer_errors.LOCK_WINDOW_S]).

    Args:
        longest_run_periods: The longest run, periods.
        Ts: Control period, s.
    """
    return longest_run_periods * Ts > LOCK_WINDOW_S


# --- over a full record (NumPy float64) -------------------------------------------------------------


def _f64(x) -> np.ndarray:
    return np.asarray(x, np.float64)


def rms_and_max_abs(x, axis=None) -> tuple[np.ndarray, np.ndarray]:
    """``(sqrt(mean(x^2)), max |x|)`` of the samples of ``x`` (NumPy).

    Args:
        x: Samples.
        axis: Axis to reduce (all when ``None``).
    """
    return np.sqrt(np.mean(x**2, axis=axis)), np.max(np.abs(x), axis=axis)


def longest_run(flags) -> int:
    """Length of the longest run of consecutive True.

    Args:
        flags: ``(N,)`` booleans.
    """
    best = run = 0
    for f in np.asarray(flags, bool):
        run = out_of_lock_run(run, f)
        best = max(best, run)
    return int(best)


def observer_errors(
    trace,
    Ts: float,
    converged_after_s: float = CONVERGED_AFTER_S,
    modulo_pi: bool = False,
    speed_lock: bool = True,
) -> dict:
    """The observer figures of one run (module docstring).

    Args:
        trace: The run's full-rate [`Trace`][pmsmjax.trace.Trace].
        Ts: Control period, s.
        converged_after_s: Periods before this time are not counted, s.
        modulo_pi: Take the angle error and the lock criterion modulo pi.
        speed_lock: Judge lock on the speed error too (else on the angle alone).

    Returns:
        ``angle_error_rms_deg``, ``angle_error_max_deg`` (electrical degrees), ``speed_error_rms_rpm``
        (estimate against the plant), ``speed_tracking_rms_rpm`` (plant against the reference), all after
        convergence; ``lock_lost`` (bool) and ``longest_out_of_lock_s``.
    """
    t = _f64(trace.t)
    after = t >= converged_after_s - 0.5 * Ts
    error = angle_error_modulo_pi if modulo_pi else angle_error
    e_theta = error(_f64(trace.theta_e_est), _f64(trace.theta_e))[after]
    w = _f64(trace.omega_m)[after]
    e_speed = _f64(trace.omega_m_est)[after] - w
    ref = _f64(trace.speed_ref)[after]
    longest = longest_run(out_of_lock(e_theta, e_speed, ref, modulo_pi, speed_lock))
    angle_rms, angle_max = rms_and_max_abs(e_theta)
    speed_rms, speed_max = rms_and_max_abs(e_speed)
    tracking_rms, _ = rms_and_max_abs(tracking_error(ref, w))
    return {
        "angle_error_rms_deg": float(np.degrees(angle_rms)),
        "angle_error_max_deg": float(np.degrees(angle_max)),
        "speed_error_rms_rpm": float(rad_s_to_rpm(speed_rms)),
        "speed_error_max_rpm": float(rad_s_to_rpm(speed_max)),
        "speed_tracking_rms_rpm": float(rad_s_to_rpm(tracking_rms)),
        "lock_lost": bool(lock_lost(longest, Ts)),
        "longest_out_of_lock_s": float(longest * Ts),
        "angle_modulo": "pi" if modulo_pi else "2pi",
    }


def speed_held(trace, Ts: float, judge_from_s: float, converged_after_s: float = CONVERGED_AFTER_S) -> dict:
    """Whether the run held its final speed reference from ``judge_from_s`` to its end (see the module
    docstring).

    Args:
        trace: The run's full-rate trace.
        Ts: Control period, s.
        judge_from_s: Start of the judged window, s.
        converged_after_s: Periods before this time are not counted for lock, s.

    Returns:
        ``held`` and the figures it is judged on: ``speed_error_max_rpm``, ``angle_error_max_deg``
        (electrical degrees), ``lock_lost``.
    """
    t = _f64(trace.t)
    window = t >= judge_from_s - 0.5 * Ts
    ref = _f64(trace.speed_ref)[window]
    _, speed_err = rms_and_max_abs(tracking_error(ref, _f64(trace.omega_m)[window]))
    _, angle_max = rms_and_max_abs(angle_error(_f64(trace.theta_e_est), _f64(trace.theta_e))[window])
    limit = HELD_SPEED_FRACTION * np.min(np.abs(ref))
    lost = observer_errors(trace, Ts, converged_after_s)["lock_lost"]
    return {
        "held": bool(speed_err <= limit and angle_max <= HELD_ANGLE_RAD and not lost),
        "speed_error_max_rpm": float(rad_s_to_rpm(speed_err)),
        "angle_error_max_deg": float(np.degrees(angle_max)),
        "lock_lost": lost,
    }


def error_statistics(
    time, theta_est, omega_est, theta_true, omega_true, settle_s: float = 0.0, modulo_pi: bool = False
) -> dict:
    """Angle and speed error figures of an estimate against the truth.

    NumPy floats computed in the precision of the inputs (a log's float64).

    Args:
        time: ``(N,)`` sample times, s.
        theta_est: ``(N,)`` estimated electrical angle, rad.
        omega_est: ``(N,)`` estimated speed, rad/s.
        theta_true: ``(N,)`` true electrical angle, rad.
        omega_true: ``(N,)`` true speed, rad/s.
        settle_s: Rows before this time from the first row are left out, s.
        modulo_pi: Take the angle error modulo pi
            ([`angle_error`][pmsmjax.analysis.observer_errors.angle_error]).

    Returns:
        ``angle_rms_deg``, ``angle_mean_deg``, ``angle_max_deg`` (electrical degrees), ``speed_rms_rpm``,
        ``speed_max_rpm`` (mechanical r/min), ``samples``.
    """
    t = np.asarray(time)
    keep = t >= t[0] + settle_s
    error = angle_error_modulo_pi if modulo_pi else angle_error
    e = error(np.asarray(theta_est), np.asarray(theta_true))[keep]
    w = (np.asarray(omega_est) - np.asarray(omega_true))[keep]
    angle_rms, angle_max = rms_and_max_abs(e)
    speed_rms, speed_max = rms_and_max_abs(w)
    return {
        "angle_rms_deg": float(np.degrees(angle_rms)),
        "angle_mean_deg": float(np.degrees(np.mean(e))),
        "angle_max_deg": float(np.degrees(angle_max)),
        "speed_rms_rpm": float(rad_s_to_rpm(speed_rms)),
        "speed_max_rpm": float(rad_s_to_rpm(speed_max)),
        "samples": int(keep.sum()),
    }


# --- over a traced window (jnp, differentiable) -------------------------------------------------------


def _safe_sqrt(x):
    """``sqrt(x)`` with a zero derivative at ``x = 0`` (double where: the exact sensor's angle error is 0,
    where sqrt's derivative is infinite)."""
    positive = ~(x <= 0)  # NaN (a diverged run) counts as positive, so it propagates instead of reading 0
    return jnp.where(positive, jnp.sqrt(jnp.where(positive, x, 1.0)), 0.0)


def angle_error_rms(theta_est, theta, weight, period: float = 2.0 * math.pi):
    """RMS of [`angle_error`][pmsmjax.analysis.observer_errors.angle_error] over the weighted samples;
    differentiable, with a zero derivative where the error is exactly 0.

    Args:
        theta_est: ``(N,)`` estimated angle, rad.
        theta: ``(N,)`` true angle, rad.
        weight: ``(N,)`` 1.0 where a sample counts (e.g. after the observer takes over and inside the
            scenario).
        period: The period the error is wrapped to, rad.

    Returns:
        The RMS error, electrical rad.
    """
    n = jnp.maximum(jnp.sum(weight), 1.0)
    return _safe_sqrt(jnp.sum(angle_error(theta_est, theta, period) ** 2 * weight) / n)


def angle_chord_rms(theta_est, theta, weight, period: float = 2.0 * math.pi):
    """[`angle_error_rms`][pmsmjax.analysis.observer_errors.angle_error_rms] with each error ``e`` counted as
    its chord ``2 sin(e/2)`` (module docstring); with period pi the chord of ``2e`` halved, ``sin(e)``.

    Args:
        theta_est: ``(N,)`` estimated angle, rad.
        theta: ``(N,)`` true angle, rad.
        weight: ``(N,)`` 1.0 where a sample counts.
        period: The period the error is wrapped to, rad.
    """
    m = 2.0 * math.pi / period
    chord_squared = (2.0 - 2.0 * jnp.cos(m * (theta_est - theta))) / m**2
    n = jnp.maximum(jnp.sum(weight), 1.0)
    return _safe_sqrt(jnp.sum(chord_squared * weight) / n)
