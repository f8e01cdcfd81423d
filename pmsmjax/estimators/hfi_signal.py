"""The high-frequency carrier shared by the injection estimators (the book, ch. 6): its sampled phase,
the band-pass filter that separates it from the fundamental, and the HF current a salient machine
answers with.

**HF model.** At the injection frequency ``w_h`` the resistance and back-EMF are negligible (the book, ch. 6:
``u_dh = L_d di_dh/dt``, ``u_qh = L_q di_qh/dt``), so the HF current is the inverse inductance times the HF
flux ``psi_h = int u_h dt``. In complex stationary-frame notation (``x = x_a + j x_b``) the salient
inductance of the book, ch. 1 is ``psi = L0 i + L2 e^{j 2 th} conj(i)`` with ``L0 = (L_d + L_q)/2``,
``L2 = (L_d - L_q)/2``, whose inverse is

    i = (L0 psi - L2 e^{j 2 th} conj(psi)) / (L_d L_q).

For a rotating flux ``psi_h = Psi e^{j phi}``: ``i_h = I_p e^{j phi} + I_n e^{j (2 th - phi)}`` with
``I_p = L0 Psi / (L_d L_q)`` and ``I_n = -L2 Psi / (L_d L_q) = (L_q - L_d) Psi / (2 L_d L_q)`` (positive
when ``L_q > L_d``): the negative-sequence current carries ``2 th``, hence the angle modulo pi.

**Sampled carrier.** The estimator computes the carrier command ``V_h e^{j x k}`` at sample ``k``
(``x = w_h Ts``); the drive holds it over one period, ``delay_periods - 1/2`` periods later (1.5 for the
book drive: one period of computational delay plus the zero-order hold's half period). Summing the held
voltages, the flux at sample ``n`` is exactly

    psi_n = V_h Ts / (2 sin(x/2)) e^{j (x n - delay_periods x - pi/2)},

so the flux amplitude is ``Psi = V_h / w_eff`` with ``w_eff = 2 sin(x/2)/Ts`` (``w_h`` for ``Ts -> 0``:
1.6 % below ``w_h`` at 1 kHz, 10 kHz) and its phase [`flux_phase`][pmsmjax.estimators.hfi_signal.flux_phase]
lags the command by ``delay_periods x + pi/2``. The demodulators use this phase, so the delay is compensated
exactly.

**Band-pass filter.** A second-order digital resonator (Bristow-Johnson's audio-EQ-cookbook band-pass,
constant 0 dB peak) centred exactly at ``x``: unit gain and zero phase at ``w_h`` whatever the bandwidth,
zeros at DC and Nyquist, -3 dB bandwidth ``B`` (rad/s; ``Q = w_h / B``). ``i - BPF(i)`` is the matching
notch: the fundamental current the current loop sees (the carrier never enters its feedback). Off-centre
the resonator delays: a carrier image at ``w_h + d`` is shifted by ``arg H(e^{j (x + d Ts)})``
(``-atan(2 d / B)`` in the analog limit), which at low speed is a delay of ``2/B`` s on the rotor's image;
each estimator takes it out of its output angle exactly
([`bandpass_phase`][pmsmjax.estimators.hfi_signal.bandpass_phase]).
"""

import math

import equinox as eqx
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.estimators.pll import pll_design
from pmsmjax.frames.three_phase import wrap_angle
from pmsmjax.machines.motor import as_float
from pmsmjax.spec.validation import ParameterError, check_positive, is_concrete

#: Default carrier frequency as a fraction of the sampling frequency: 10 samples per carrier period, far
#: below the 5 kHz Nyquist frequency of 10 kHz control, far above the ~175 Hz current-loop bandwidth.
CARRIER_FRACTION = 0.1
#: Default band-pass quality ``Q = w_h / B`` (B = 1257 rad/s at 1 kHz): passes the carrier's images at
#: ``w_h +- 2 w_e`` for low speeds with a small, compensated delay, and attenuates the fundamental's
#: transients at the current-loop bandwidth (1100 rad/s) by about 15 dB.
BANDPASS_Q = 5.0
#: Negative-sequence current amplitude the voltage design rule aims at, A: about 3 % of the 9.1 A the
#: book's 10 N m load needs, and 25 LSB of a 12-bit converter on a +-20 A range.
TARGET_NEGATIVE_SEQUENCE_A = 0.25


class BandpassState(eqx.Module):
    x1: Array  # (2,) input one sample ago
    x2: Array  # (2,) input two samples ago
    y1: Array  # (2,) output one sample ago
    y2: Array  # (2,) output two samples ago


def bandpass_coefficients(w_h, bandwidth, Ts: float):
    """``(b0, a1, a2)`` of the resonator ``H(z) = b0 (1 - z^-2) / (1 + a1 z^-1 + a2 z^-2)`` centred at
    ``w_h`` (rad/s) with -3 dB bandwidth ``bandwidth`` (rad/s), period ``Ts`` (s)."""
    x = w_h * Ts
    alpha = jnp.sin(x) * bandwidth / (2.0 * w_h)  # sin(x) / (2 Q)
    a0 = 1.0 + alpha
    return alpha / a0, -2.0 * jnp.cos(x) / a0, (1.0 - alpha) / a0


def bandpass_init(dtype) -> BandpassState:
    """The resonator's zero state (inputs and outputs of the last two samples, ``(2,)`` each) of `dtype`."""
    z = jnp.zeros(2, dtype)
    return BandpassState(z, z, z, z)


def bandpass_step(state: BandpassState, x: Array, coefficients) -> tuple[BandpassState, Array]:
    """One sample of the resonator on both axes: ``x (2,)`` -> ``(state, y (2,))``."""
    b0, a1, a2 = coefficients
    y = b0 * (x - state.x2) - a1 * state.y1 - a2 * state.y2
    return BandpassState(x, state.x1, y, state.y1), y


def bandpass_phase(frequency, coefficients, Ts: float) -> Array:
    """Phase of the resonator at ``frequency`` (rad/s, may be traced), rad: ``arg H(e^{j frequency Ts})``."""
    b0, a1, a2 = coefficients
    v = frequency * Ts
    # H = b0 (1 - e^{-2jv}) / (1 + a1 e^{-jv} + a2 e^{-2jv}); numerator phase is pi/2 - v (for b0 > 0)
    re = 1.0 + a1 * jnp.cos(v) + a2 * jnp.cos(2.0 * v)
    im = -a1 * jnp.sin(v) - a2 * jnp.sin(2.0 * v)
    return wrap_angle(0.5 * jnp.pi - v - jnp.arctan2(im, re))


def flux_phase(carrier_phase, w_h, Ts: float, delay_periods: float) -> Array:
    """Phase of the HF flux at the sampling instant whose carrier command has phase ``carrier_phase``
    (rad): ``carrier_phase - delay_periods w_h Ts - pi/2`` (module docstring)."""
    return carrier_phase - delay_periods * w_h * Ts - 0.5 * jnp.pi


def effective_frequency(w_h, Ts: float) -> Array:
    """``2 sin(w_h Ts / 2) / Ts``, rad/s: the held carrier's flux is ``V_h`` divided by this."""
    return 2.0 * jnp.sin(0.5 * w_h * Ts) / Ts


def negative_sequence_amplitude(L_d, L_q, V_h, w_h, Ts: float) -> Array:
    """``I_n = (L_q - L_d) V_h / (2 L_d L_q w_eff)``, A: the negative-sequence (rotating injection) and
    the q-axis error-signal (pulsating injection) amplitude for carrier amplitude ``V_h`` (V) at ``w_h``
    (rad/s) held over periods ``Ts`` (s); ``w_eff`` from
    [`effective_frequency`][pmsmjax.estimators.hfi_signal.effective_frequency]."""
    return (L_q - L_d) * V_h / (2.0 * L_d * L_q * effective_frequency(w_h, Ts))


def lowpass_gain(cutoff, Ts: float) -> Array:
    """Per-sample gain ``1 - exp(-cutoff Ts)`` of the exact sampled first-order low-pass (cut-off rad/s)."""
    return 1.0 - jnp.exp(-cutoff * Ts)


def check_carrier(owner: str, w_h, bandwidth, Ts: float) -> None:
    """Refuse a carrier the sampled chain cannot carry: ``w_h`` at or above a quarter of the sampling
    frequency's angular value times 2 pi (fewer than 4 samples per period), or a band wider than ``w_h``."""
    if not (is_concrete(w_h) and is_concrete(bandwidth)):
        return
    w, b = float(jnp.max(w_h)), float(jnp.max(bandwidth))
    limit = 0.5 * math.pi / Ts
    if w >= limit:
        raise ParameterError(
            f"{owner}: carrier {w / (2 * math.pi):.4g} Hz is too close to Nyquist for Ts = {Ts:g} s "
            f"(fewer than 4 samples per carrier period): choose hf_frequency <= {0.1 / Ts:.4g} Hz "
            f"(10 samples per period)."
        )
    if b >= w:
        raise ParameterError(
            f"{owner}: band-pass bandwidth {b:g} rad/s is not below the carrier {w:g} rad/s: "
            f"give a bandwidth near w_h / {BANDPASS_Q:g}."
        )


def check_salient(owner: str, L_d, L_q) -> None:
    """HF injection reads the saliency: refuse a model with ``L_q <= L_d`` (surface machine)."""
    if is_concrete(L_d) and is_concrete(L_q) and float(jnp.min(L_q - L_d)) <= 0.0:
        raise ParameterError(
            f"{owner} needs a salient machine (L_q > L_d), got L_d = {float(jnp.max(L_d)):g} H, "
            f"L_q = {float(jnp.min(L_q)):g} H: use the salient preset (--motor book_salient) or a "
            "chapter 5 observer."
        )


def injection_design(
    owner: str, motor, Ts: float, *, hf_frequency, hf_voltage, bandpass_q, error_cutoff, pll_bandwidth,
    theta0, delay_periods, filter_feedback,
) -> dict:  # fmt: skip
    """The constructor fields both injection design rules share, as keywords of
    [`HFIPulsating`][pmsmjax.estimators.hfi_pulsating.HFIPulsating] and
    [`HFIRotating`][pmsmjax.estimators.hfi_rotating.HFIRotating].

    The carrier frequency defaults to ``f_s / 10`` (``hf_frequency`` Hz overrides), ``V_h`` to the voltage
    giving a [`TARGET_NEGATIVE_SEQUENCE_A`][pmsmjax.estimators.hfi_signal.TARGET_NEGATIVE_SEQUENCE_A]
    error-signal amplitude at the held carrier's effective frequency, the resonator bandwidth to
    ``w_h / bandpass_q``, the error low-pass to ``w_h / 3`` and the PLL bandwidth to a seventh of it (rad/s);
    ``owner`` names the estimator in the errors.
    """
    f_h = 0.1 / Ts if hf_frequency is None else float(hf_frequency)
    check_positive("hf_frequency", f_h, "Hz", f"a carrier near {0.1 / Ts:g} Hz (f_s / 10)")
    check_positive("bandpass_q", bandpass_q, "", "Q = w_h / B, e.g. 5")
    w_h = 2.0 * math.pi * f_h
    check_salient(owner, motor.L_d, motor.L_q)
    if hf_voltage is None:
        per_volt = negative_sequence_amplitude(motor.L_d, motor.L_q, 1.0, w_h, Ts)
        hf_voltage = TARGET_NEGATIVE_SEQUENCE_A / per_volt
    w_l = w_h / 3.0 if error_cutoff is None else error_cutoff
    return dict(
        L_d=motor.L_d,
        L_q=motor.L_q,
        pole_pairs=motor.pole_pairs,
        hf_voltage=hf_voltage,
        hf_omega=w_h,
        bandpass_bandwidth=w_h / bandpass_q,
        error_cutoff=w_l,
        pll=pll_design(as_float(w_l) / 7.0 if pll_bandwidth is None else pll_bandwidth),
        theta0=theta0,
        delay_periods=float(delay_periods),
        filter_feedback=bool(filter_feedback),
    )


def highpass_complement_phase(v, gain) -> Array:
    """Phase, rad, of ``1 - LPF`` at the per-sample frequency ``v`` (rad/sample) for the first-order
    low-pass ``y_k = y_{k-1} + gain (u_k - y_{k-1})``: ``1 - LPF = (1 - gain)(1 - e^{-jv}) /
    (1 - (1 - gain) e^{-jv})``. What the negative-sequence image keeps of its phase when the positive
    sequence is removed by subtracting its low-passed copy."""
    a = 1.0 - gain
    num = jnp.arctan2(jnp.sin(v), 1.0 - jnp.cos(v))  # arg(1 - e^{-jv})
    den = jnp.arctan2(a * jnp.sin(v), 1.0 - a * jnp.cos(v))  # arg(1 - a e^{-jv})
    return num - den


def cmul(a: Array, b: Array) -> Array:
    """Complex product of two ``(2,)`` vectors read as ``x_a + j x_b``."""
    return jnp.stack([a[0] * b[0] - a[1] * b[1], a[0] * b[1] + a[1] * b[0]])


def conj(a: Array) -> Array:
    """Complex conjugate of a ``(2,)`` vector read as ``x_a + j x_b``."""
    return jnp.stack([a[0], -a[1]])


def unit(phase) -> Array:
    """``e^{j phase}`` as a ``(2,)`` vector."""
    return jnp.stack([jnp.cos(phase), jnp.sin(phase)])
