"""Figures of merit of a sensorless drive's observer (issue 14, BOOK.md chapter 5): angle and speed
estimation error, loss of lock, and whether a speed is held under load.

One definition serves :func:`pmsmjax.studies.control_comparison.compare_estimators` (NumPy, on a full trace)
and the Monte Carlo kernel (:mod:`tuning.montecarlo.kernel`, accumulated inside the scan); the tests check
one against the other.

- **Angle error** ``e_theta = wrap(theta_e_est - theta_e)``, electrical rad wrapped to [-pi, pi), at each
  period start (the sampling instant, where the observer's estimate and the plant's angle belong together).
- **Speed estimation error** ``omega_m_est - omega_m``, mechanical rad/s.
- **After convergence**: only periods starting at or after ``converged_after_s`` count (the I/f start-up's
  hand-over of the book drive ends at 26 ms; :data:`CONVERGED_AFTER_S` leaves the observer and the speed
  loop 24 ms more).
- **Loss of lock**: after convergence, a run of more than ``lock_window_s`` (:data:`LOCK_WINDOW_S`, 10 ms:
  longer than any transient of a locked observer, shorter than the load-step recovery) consecutive periods
  that are each *out of lock*: ``|e_theta| > 90 deg el`` (the controller then produces torque of the
  wrong sign) or ``|omega_m_est - omega_m| > 0.5 |omega*| + 1 rad/s`` (half the reference; the 1 rad/s
  floor keeps a zero reference meaningful).
- **Modulo pi** (``modulo_pi=True``, the chapter 6 injection estimators, which find the d axis without
  its polarity): the angle error is ``wrap(2 e_theta) / 2`` in [-pi/2, pi/2), and out of lock by angle is
  ``|e_theta| > 45 deg el`` (:data:`LOCK_ANGLE_MODULO_PI_RAD`): the saliency error signal
  ``~ sin(2 e_theta)`` has its unstable equilibrium at 90 degrees, and half-way to it is the same margin
  the 90 degrees give a back-EMF observer, whose torque changes sign at 180.
- **Angle-only lock** (``speed_lock=False``, the fixed low-speed scenarios of ``compare --estimator``:
  standstill and the 60 r/min reversal under a load step): only the angle criterion counts. There the
  reference is (near) zero while the load step throws the rotor to ~360 r/min and back within 50 ms; the
  speed criterion's 1 rad/s floor then flags the estimate's lag behind that transient (measured with
  ``hfi-rotating``: up to 180 r/min for 50 ms while the angle error stayed within 11 deg el), which is
  no loss of lock.
- **Held** (:func:`speed_held`): over a judging window, ``max |omega* - omega| <= 0.1 |omega*|`` and
  ``max |e_theta| <= 30 deg el``, and the run lost no lock.
"""

import math

import numpy as np

#: Periods before this time (s) are not counted (I/f start and hand-over of the book drive, then 24 ms).
CONVERGED_AFTER_S = 0.05
#: A loss of lock is out-of-lock for longer than this (s).
LOCK_WINDOW_S = 0.01
#: Out of lock: angle error beyond this (electrical rad) ...
LOCK_ANGLE_RAD = math.pi / 2
#: ... or, scored modulo pi (injection without polarity), beyond this (electrical rad).
LOCK_ANGLE_MODULO_PI_RAD = math.pi / 4
#: ... or speed estimation error beyond this fraction of |omega*| plus :data:`LOCK_SPEED_FLOOR_RAD_S`.
LOCK_SPEED_FRACTION = 0.5
LOCK_SPEED_FLOOR_RAD_S = 1.0
#: Held: speed error at most this fraction of |omega*| and angle error at most this (electrical rad).
HELD_SPEED_FRACTION = 0.1
HELD_ANGLE_RAD = math.radians(30.0)


def angle_error(theta_est, theta) -> np.ndarray:
    """``wrap(theta_est - theta)`` in [-pi, pi), rad (same shapes)."""
    d = np.asarray(theta_est, np.float64) - np.asarray(theta, np.float64)
    return (d + np.pi) % (2.0 * np.pi) - np.pi


def angle_error_modulo_pi(theta_est, theta) -> np.ndarray:
    """``wrap(2 (theta_est - theta)) / 2`` in [-pi/2, pi/2), rad: the error of an estimate of the d axis
    without its polarity (same shapes)."""
    return 0.5 * angle_error(2.0 * np.asarray(theta_est, np.float64), 2.0 * np.asarray(theta, np.float64))


def out_of_lock(e_theta, e_speed, speed_ref, modulo_pi: bool = False, speed_lock: bool = True) -> np.ndarray:
    """Per-period out-of-lock flags (see the module docstring); arrays of one shape."""
    limit = LOCK_SPEED_FRACTION * np.abs(speed_ref) + LOCK_SPEED_FLOOR_RAD_S
    angle_limit = LOCK_ANGLE_MODULO_PI_RAD if modulo_pi else LOCK_ANGLE_RAD
    out = np.abs(e_theta) > angle_limit
    return out | (np.abs(e_speed) > limit) if speed_lock else out


def longest_run(flags) -> int:
    """Length of the longest run of consecutive True in ``flags (N,)``."""
    best = run = 0
    for f in np.asarray(flags, bool):
        run = run + 1 if f else 0
        best = max(best, run)
    return best


def observer_errors(
    trace,
    Ts: float,
    converged_after_s: float = CONVERGED_AFTER_S,
    modulo_pi: bool = False,
    speed_lock: bool = True,
) -> dict:
    """The observer figures of one run from its full-rate :class:`~pmsmjax.trace.Trace` (period ``Ts``, s);
    with ``modulo_pi`` the angle error and the lock criterion are taken modulo pi, without ``speed_lock``
    lock is judged on the angle alone (module docstring).

    **Returns:** ``angle_error_rms_deg``, ``angle_error_max_deg`` (electrical degrees),
    ``speed_error_rms_rpm`` (estimate against the plant), ``speed_tracking_rms_rpm`` (plant against
    the reference), all after convergence; ``lock_lost`` (bool) and ``longest_out_of_lock_s``.
    """
    t = np.asarray(trace.t, np.float64)
    after = t >= converged_after_s - 0.5 * Ts
    error = angle_error_modulo_pi if modulo_pi else angle_error
    e_theta = error(trace.theta_e_est, trace.theta_e)[after]
    w = np.asarray(trace.omega_m, np.float64)[after]
    e_speed = np.asarray(trace.omega_m_est, np.float64)[after] - w
    ref = np.asarray(trace.speed_ref, np.float64)[after]
    longest = longest_run(out_of_lock(e_theta, e_speed, ref, modulo_pi, speed_lock))
    rpm = 30.0 / np.pi
    return {
        "angle_error_rms_deg": float(np.degrees(np.sqrt(np.mean(e_theta**2)))),
        "angle_error_max_deg": float(np.degrees(np.max(np.abs(e_theta)))),
        "speed_error_rms_rpm": float(rpm * np.sqrt(np.mean(e_speed**2))),
        "speed_error_max_rpm": float(rpm * np.max(np.abs(e_speed))),
        "speed_tracking_rms_rpm": float(rpm * np.sqrt(np.mean((ref - w) ** 2))),
        "lock_lost": bool(longest * Ts > LOCK_WINDOW_S),
        "longest_out_of_lock_s": float(longest * Ts),
        "angle_modulo": "pi" if modulo_pi else "2pi",
    }


def speed_held(trace, Ts: float, judge_from_s: float, converged_after_s: float = CONVERGED_AFTER_S) -> dict:
    """Whether the run held its final speed reference from ``judge_from_s`` (s) to its end (see the
    module docstring); returns ``held`` and the figures it is judged on (r/min, electrical degrees)."""
    t = np.asarray(trace.t, np.float64)
    window = t >= judge_from_s - 0.5 * Ts
    ref = np.asarray(trace.speed_ref, np.float64)[window]
    w = np.asarray(trace.omega_m, np.float64)[window]
    e_theta = angle_error(trace.theta_e_est, trace.theta_e)[window]
    speed_err = float(np.max(np.abs(ref - w)))
    limit = float(HELD_SPEED_FRACTION * np.min(np.abs(ref)))
    angle_max = float(np.max(np.abs(e_theta)))
    lost = observer_errors(trace, Ts, converged_after_s)["lock_lost"]
    rpm = 30.0 / np.pi
    return {
        "held": bool(speed_err <= limit and angle_max <= HELD_ANGLE_RAD and not lost),
        "speed_error_max_rpm": rpm * speed_err,
        "angle_error_max_deg": float(np.degrees(angle_max)),
        "lock_lost": lost,
    }
