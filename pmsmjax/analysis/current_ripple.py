"""Current ripple and tracking of phase currents: the ripple about a moving mean (RMS and peak to peak), the
reference phase currents of a current loop and the RMS and peak error against them."""

from pmsmjax._types import Array
from pmsmjax.analysis.array_namespace import namespace as _namespace
from pmsmjax.frames.three_phase import dq_to_abc
from pmsmjax.spec.validation import ParameterError


def ripple_about_moving_mean(y: Array, window: int) -> Array:
    """Deviation of ``y`` from its centred ``window``-sample moving mean.

    ``window`` should span several periods of the ripple and be short beside the slow trends it removes:
    a 101-sample window at 10 kHz (10 ms) spans four periods of the 420 Hz sign-law chattering of the book
    SMC drive, and leaves of a 20 ms exponential decay a residual of ``sinh(W/2 tau)/(W/2 tau) - 1`` = 1 %
    of its local value (W = 10 ms, tau = 20 ms). The mean is a difference of cumulative sums of
    ``y - mean(y)`` (centred first, so float32 records of large offsets keep their precision).

    Args:
        y: ``(..., N)`` samples.
        window: Moving-mean length in samples (static int, odd for exact centring).

    Returns:
        ``(..., N - window + 1)`` deviations, units of y.
    """
    xp = _namespace(y, window)
    n = y.shape[-1]
    if not isinstance(window, int) or not 1 <= window <= n:
        raise ParameterError(f"window must be an int in [1, {n}] samples, got {window!r}.")
    z = y - xp.mean(y, axis=-1, keepdims=True)
    cs = xp.cumsum(z, axis=-1)
    cs = xp.concatenate([xp.zeros(cs.shape[:-1] + (1,), cs.dtype), cs], axis=-1)
    moving_mean = (cs[..., window:] - cs[..., :-window]) / window
    half = (window - 1) // 2
    return z[..., half : half + n - window + 1] - moving_mean


def current_ripple_rms_a(i: Array, window: int) -> Array:
    """RMS of a current (e.g. the speed loop's ``i_q*``) about its moving mean: the chattering metric.

    Args:
        i: ``(..., N)`` samples, A, taken in steady state (the caller slices the window).
        window: Moving-mean length in samples (see
            [`ripple_about_moving_mean`][pmsmjax.analysis.metrics.ripple_about_moving_mean]).

    Returns:
        The RMS ripple, A.
    """
    xp = _namespace(i, window)
    dev = ripple_about_moving_mean(i, window)
    return xp.sqrt(xp.mean(dev * dev, axis=-1))


def current_ripple_peak_to_peak_a(i: Array, window: int) -> Array:
    """Peak-to-peak of a current about its moving mean (see
    [`current_ripple_rms_a`][pmsmjax.analysis.metrics.current_ripple_rms_a]).

    Args:
        i: ``(..., N)`` samples, A.
        window: Moving-mean length in samples.

    Returns:
        The peak-to-peak ripple, A.
    """
    xp = _namespace(i, window)
    dev = ripple_about_moving_mean(i, window)
    return xp.max(dev, axis=-1) - xp.min(dev, axis=-1)


# --- current tracking of switching controllers (hysteresis current control, table DTC) --------------------


def reference_phase_currents(i_dq_ref: Array, theta_e_est: Array) -> Array:
    """Reference phase currents: what a hysteresis controller compares with.

    From a trace: ``reference_phase_currents(trace.i_dq_ref, trace.theta_e_est)``.

    Args:
        i_dq_ref: ``(N, 2)`` dq current reference, A.
        theta_e_est: ``(N,)`` the controller's (estimated) electrical angle, rad.

    Returns:
        ``(N, 3)`` phase currents, A.
    """
    return dq_to_abc(i_dq_ref, theta_e_est)


def current_error_rms_a(i_abc: Array, i_abc_ref: Array) -> Array:
    """RMS of the phase-current error ``i_abc - i_abc_ref`` over the record and the phases.

    Pass a steady-state window (e.g. ``trace[k0:]``). It includes any mean tracking error as well as the
    ripple (hysteresis control has almost none). With switch states held between samples the current is
    nearly linear between samples, so its extremes lie on the samples and sampled records resolve the
    ripple.

    Args:
        i_abc: ``(N, 3)`` phase currents, A.
        i_abc_ref: ``(N, 3)`` reference phase currents, A.

    Returns:
        The RMS error, A.
    """
    xp = _namespace(i_abc, i_abc_ref)
    err = i_abc - i_abc_ref
    return xp.sqrt(xp.mean(err * err, axis=(-2, -1)))


def current_error_peak_a(i_abc: Array, i_abc_ref: Array) -> Array:
    """Largest absolute phase-current error ``|i_abc - i_abc_ref|`` over the record and the phases.

    Args:
        i_abc: ``(N, 3)`` phase currents, A.
        i_abc_ref: ``(N, 3)`` reference phase currents, A.

    Returns:
        The peak error, A.
    """
    xp = _namespace(i_abc, i_abc_ref)
    return xp.max(xp.abs(i_abc - i_abc_ref), axis=(-2, -1))
