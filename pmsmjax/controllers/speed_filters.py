"""Speed-loop filters for a compliant shaft: a low-pass on the speed feedback and a notch on the torque
(q-current) reference, both run once per speed-loop period and both optional.

**Low-pass** (cut-off ``f_c``, Hz) on the measured speed: ``y_k = y_{k-1} + a (w_k - y_{k-1})``,
``a = 1 - exp(-2 pi f_c T)`` (``T`` the speed loop's period): the exact sampled first-order lag for an input
held over the period. It takes the encoder's speed ripple and the resonance's high-frequency share out of the
proportional path, at the cost of phase at the loop's crossover (a cut-off some 3 to 10 times the speed
bandwidth is the usual compromise; Wang and Shen, "Detection and reduction of middle-frequency resonance for
industrial servo with self-tuning lowpass filter", J. Control Sci. Eng. 2012, doi:10.1155/2012/478907, tune
it in the speed feedback of a servo for the same reason).

**Notch** (centre ``f_n``, width ``W``, depth ``d``) on the speed PI's output:

    ``N(s) = (s^2 + 2 zeta_z w_n s + w_n^2) / (s^2 + 2 zeta_p w_n s + w_n^2)``,

``w_n = 2 pi f_n``, ``zeta_p = W / (2 f_n)`` (the -3 dB width of a deep notch is ``2 zeta_p f_n``),
``zeta_z = zeta_p 10^(-d/20)`` (the gain at ``f_n`` is ``zeta_z / zeta_p``: ``d`` dB down). Unit gain at DC
and at high frequency; phase lag below ``f_n``, lead above. It is discretised by the bilinear (Tustin)
transform prewarped at the notch frequency, ``s = K (z - 1)/(z + 1)`` with ``K = w_n / tan(w_n T / 2)``, so
that the discrete notch has its centre exactly at ``f_n`` (the plain Tustin map would shift it down by the
frequency warping, by 4 % at a fifth of the sampling rate); realised as a direct-form II transposed biquad.
``f_n`` must lie below the speed loop's Nyquist frequency ``1 / (2 T)``
([`check_rate`][pmsmjax.controllers.speed_filters.SpeedLoopFilters.check_rate]).

Every parameter is an array leaf: the coefficients are computed from them inside the step, so tuning moves
the notch and the cut-off by gradients (``pmsmjax tune`` over a spread of shaft resonances).
"""

import equinox as eqx
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.machines.motor import optional_float
from pmsmjax.spec.validation import ParameterError, check_positive, is_concrete

__all__ = ["SpeedLoopFilters", "notch_coefficients", "low_pass_gain"]

#: The deepest notch accepted, dB (a notch's depth is 10 to 40 dB in servo drives; 60 dB is a zero on the
#: unit circle to float32 resolution).
MAX_NOTCH_DEPTH_DB = 60.0


def low_pass_gain(cutoff_hz, Ts) -> Array:
    """``a = 1 - exp(-2 pi f_c T)`` of the sampled first-order low-pass (module docstring).

    Args:
        cutoff_hz: Cut-off frequency, Hz.
        Ts: The filter's sampling period, s.
    """
    return -jnp.expm1(-2.0 * jnp.pi * cutoff_hz * Ts)


def notch_coefficients(notch_hz, width_hz, depth_db, Ts) -> tuple[Array, Array]:
    """The prewarped Tustin notch's ``(b (3,), a (3,))``, ``a[0] = 1`` (module docstring).

    Args:
        notch_hz: Centre frequency, Hz (below ``1 / (2 Ts)``).
        width_hz: Width, Hz (``2 zeta_p f_n``).
        depth_db: Attenuation at the centre, dB (> 0).
        Ts: Sampling period, s.
    """
    w_n = 2.0 * jnp.pi * notch_hz
    K = w_n / jnp.tan(0.5 * w_n * Ts)
    zeta_p = width_hz / (2.0 * notch_hz)
    zeta_z = zeta_p * 10.0 ** (-depth_db / 20.0)
    K2, w2 = K * K, w_n * w_n
    den = K2 + 2.0 * zeta_p * w_n * K + w2
    b = jnp.stack([K2 + 2.0 * zeta_z * w_n * K + w2, 2.0 * (w2 - K2), K2 - 2.0 * zeta_z * w_n * K + w2]) / den
    a = jnp.stack([den, 2.0 * (w2 - K2), K2 - 2.0 * zeta_p * w_n * K + w2]) / den
    return b, a


class SpeedLoopFilters(eqx.Module):
    """The speed loop's optional low-pass on the speed feedback and notch on the current reference (module
    docstring). A field left None is a filter left out.

    Args:
        speed_filter_hz: Low-pass cut-off on the measured speed, Hz; None: no low-pass.
        notch_hz: Notch centre, Hz; None: no notch (then also no width and depth).
        notch_width_hz: Notch width, Hz (``2 zeta_p f_n``; below ``2 notch_hz``).
        notch_depth_db: Attenuation at the centre, dB (0 < depth <= 60).

    Raises:
        ParameterError: For a non-positive frequency, width or depth, a notch without its width and depth,
            a width of twice the centre or more, or a depth beyond 60 dB.
    """

    speed_filter_hz: Array | None = eqx.field(default=None, converter=optional_float)
    notch_hz: Array | None = eqx.field(default=None, converter=optional_float)
    notch_width_hz: Array | None = eqx.field(default=None, converter=optional_float)
    notch_depth_db: Array | None = eqx.field(default=None, converter=optional_float)

    def __check_init__(self):
        notch = (self.notch_hz, self.notch_width_hz, self.notch_depth_db)
        if any(x is not None for x in notch) and any(x is None for x in notch):
            raise ParameterError(
                "a notch needs notch_hz, notch_width_hz and notch_depth_db: give all three (e.g. 200, 100, "
                "20) or none."
            )
        for name in ("speed_filter_hz", "notch_hz", "notch_width_hz", "notch_depth_db"):
            value = getattr(self, name)
            if value is not None:
                check_positive(f"SpeedLoopFilters.{name}", value, "dB" if name.endswith("db") else "Hz")
        if self.has_notch and all(is_concrete(x) for x in notch):
            f_n, width, depth = (float(jnp.max(x)) for x in notch)
            if float(jnp.min(self.notch_width_hz / self.notch_hz)) >= 2.0:
                raise ParameterError(
                    f"SpeedLoopFilters.notch_width_hz = {width:g} Hz is not below twice the notch frequency "
                    f"({f_n:g} Hz): give a width below {2 * f_n:g} Hz (half the centre is a usual notch)."
                )
            if depth > MAX_NOTCH_DEPTH_DB:
                raise ParameterError(
                    f"SpeedLoopFilters.notch_depth_db = {depth:g} dB: give an attenuation up to "
                    f"{MAX_NOTCH_DEPTH_DB:g} dB (servo notches are 10-40 dB)."
                )

    @property
    def has_notch(self) -> bool:
        """Whether the notch is in (static)."""
        return self.notch_hz is not None

    def check_rate(self, Ts: float, where: str = "SpeedLoopFilters") -> None:
        """Refuse a notch or a cut-off at or above the speed loop's Nyquist frequency ``1 / (2 Ts)``.

        Args:
            Ts: The speed loop's period, s.
            where: How the message names the filters (a drive file's ``[control]`` keys).
        """
        nyquist = 0.5 / Ts
        for name in ("speed_filter_hz", "notch_hz"):
            value = getattr(self, name)
            if value is not None and is_concrete(value) and float(jnp.max(value)) >= nyquist:
                raise ParameterError(
                    f"{where} {name} = {float(jnp.max(value)):g} Hz is at or above the speed loop's Nyquist "
                    f"frequency {nyquist:g} Hz (speed period {Ts * 1e3:g} ms): give a frequency below "
                    f"{nyquist:g} Hz, or run the speed loop faster."
                )

    def init(self, dtype) -> tuple:
        """``(low-pass state () or None, notch state (2,) or None)``, at zero."""
        low = None if self.speed_filter_hz is None else jnp.zeros((), dtype)
        return low, (jnp.zeros((2,), dtype) if self.has_notch else None)

    def steady_state(self, state: tuple, omega_m) -> tuple:
        """The filters at a constant speed ``omega_m`` (rad/s) and a zero current reference: the low-pass
        holding the speed, the notch at rest."""
        low, notch = state
        return (None if low is None else jnp.asarray(omega_m, low.dtype)), notch

    def feedback(self, state: tuple, omega_m, Ts: float) -> tuple[tuple, Array]:
        """The low-passed speed, rad/s (``omega_m`` itself without a low-pass).

        Args:
            state: The filters' state.
            omega_m: Measured speed, rad/s.
            Ts: The speed loop's period, s.

        Returns:
            ``(state, speed)``.
        """
        low, notch = state
        if low is None:
            return state, omega_m
        low = low + low_pass_gain(self.speed_filter_hz, Ts) * (omega_m - low)
        return (low, notch), low

    def reference(self, state: tuple, i_ref, Ts: float) -> tuple[tuple, Array]:
        """The notched current reference, A (``i_ref`` itself without a notch).

        Args:
            state: The filters' state.
            i_ref: The speed controller's output, A.
            Ts: The speed loop's period, s.

        Returns:
            ``(state, reference)``.
        """
        low, notch = state
        if notch is None:
            return state, i_ref
        b, a = notch_coefficients(self.notch_hz, self.notch_width_hz, self.notch_depth_db, Ts)
        y = b[0] * i_ref + notch[0]
        s1 = b[1] * i_ref - a[1] * y + notch[1]
        s2 = b[2] * i_ref - a[2] * y
        return (low, jnp.stack([s1, s2])), y
