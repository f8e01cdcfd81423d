"""Pulsating high-frequency injection on the estimated d axis (the book, ch. 6): the rotor angle modulo pi
and the speed from the saliency, at standstill and low speed.

Injection: ``u_dh = V_h cos(w_h t)``, ``u_qh = 0`` in the estimated rotor frame, turned to the stationary
frame with the estimate (``u_injection_ab``). With the estimate ``dth = th - th^`` off the d axis, the HF
flux ``psi_dh = Psi cos(phi)`` along the estimated d axis drives, through the inverse inductance in the
estimated frame ([`hfi_signal`][pmsmjax.estimators.hfi_signal]),

    i_qh^ = (L_q - L_d) / (2 L_d L_q) sin(2 dth) psi_dh = I_n sin(2 dth) cos(phi),

the same ``I_n = (L_q - L_d) V_h / (2 L_d L_q w_eff)`` as the rotating method's negative sequence, while
``i_dh^`` is large and barely depends on ``dth``.

Signal chain per sample:

1. **band-pass** ``i_h = BPF(i_ab)`` (the resonator of [`hfi_signal`][pmsmjax.estimators.hfi_signal]);
   ``i_ab - i_h`` is the fundamental current the controller gets;
2. **q-axis HF current** in the estimated frame: ``i_qh^ = Park(i_h, th^ + s)[q]``, where ``s`` is the
   resonator's rotation of the pulsating vector when the frame turns at the electrical speed ``w_e``:
   its two images at ``w_h + w_e`` and ``-(w_h - w_e)`` are shifted by ``arg H(w_h + w_e)`` and
   ``-arg H(w_h - w_e)``, i.e. the vector by ``s = (arg H(w_h + w_e) - arg H(w_h - w_e)) / 2``
   (``~ -2 w_e / B``) and the carrier by half their sum (``~ 0``);
3. **demodulation**: ``eps = LPF(2 cos(phi) i_qh^) = I_n sin(2 dth)`` (the product's ``2 w_h`` part
   filtered), scaled by ``1 / (2 I_n)`` of the model: ``~ dth`` for small errors;
4. **PLL** ([`pmsmjax.estimators.pll.PLL`][pmsmjax.estimators.pll.PLL]) -> ``th^`` (the injection axis) and
   ``w^``.

Because the demodulation frame follows the band-passed vector, the loop locks to the rotor's d axis
itself; the resonator's delay only sits in the loop as a delay of the error signal, not as an angle offset.

Filter design ([`hfi_pulsating_design`][pmsmjax.estimators.hfi_pulsating.hfi_pulsating_design]): the rotating
method's ([`hfi_rotating`][pmsmjax.estimators.hfi_rotating]): carrier ``f_s / 10``, ``B = w_h / 5``, error
low-pass ``w_h / 3``, PLL bandwidth a seventh of it, ``V_h`` for ``I_n = 0.25 A``.

Reference: J.-I. Ha, S.-K. Sul, "Sensorless field-orientation control of an induction machine by high-
frequency signal injection", IEEE TIA 35(1), 1999, doi:10.1109/28.740843; M. Linke, R. Kennel, J. Holtz,
"Sensorless position control of permanent magnet synchronous machines without limitation at zero speed",
IECON 2002, doi:10.1109/IECON.2002.1187512 (pulsating injection in the estimated d axis).
"""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.estimators import hfi_signal as hs
from pmsmjax.estimators.pll import PLL, AbstractPLLEstimator, PLLState
from pmsmjax.frames.three_phase import inverse_park, park, wrap_angle
from pmsmjax.machines.motor import PMSMParameters, as_float
from pmsmjax.signals import Estimate, Sample
from pmsmjax.spec.validation import check_positive


class HFIPulsatingState(eqx.Module):
    carrier: Array  # rad, phase of this sample's carrier command (wrapped)
    bandpass: hs.BandpassState  # current resonator
    error: Array  # A, low-passed demodulated I_n sin(2 dth)
    pll: PLLState


class HFIPulsating(AbstractPLLEstimator):
    """Pulsating-injection estimator (see the module docstring).

    **Arguments:**

    - `L_d`, `L_q`: the model's inductances, H (scale the error signal; ``L_q > L_d``).
    - `pole_pairs`: static int.
    - `hf_voltage`: carrier amplitude ``V_h`` on the estimated d axis, V.
    - `hf_omega`: carrier angular frequency ``w_h``, rad/s.
    - `bandpass_bandwidth`: resonator -3 dB bandwidth, rad/s.
    - `error_cutoff`: demodulation low-pass cut-off, rad/s.
    - `pll`: the tracking loop.
    - `theta0`: initial angle estimate, electrical rad.
    - `delay_periods`: static, periods from the carrier command to the middle of its hold (1.5 with the
      drive's computational delay, 0.5 without).
    - `filter_feedback`: static; give the controller the notch-filtered current (default) or the raw one.
    """

    injects_voltage: ClassVar[bool] = True

    L_d: Array = eqx.field(converter=as_float)
    L_q: Array = eqx.field(converter=as_float)
    pole_pairs: int = eqx.field(static=True)
    hf_voltage: Array = eqx.field(converter=as_float)
    hf_omega: Array = eqx.field(converter=as_float)
    bandpass_bandwidth: Array = eqx.field(converter=as_float)
    error_cutoff: Array = eqx.field(converter=as_float)
    pll: PLL
    theta0: Array = eqx.field(converter=as_float, default=0.0)
    delay_periods: float = eqx.field(static=True, default=1.5)
    filter_feedback: bool = eqx.field(static=True, default=True)

    def __check_init__(self):
        check_positive("HFIPulsating.hf_voltage", self.hf_voltage, "V")
        check_positive("HFIPulsating.hf_omega", self.hf_omega, "rad/s")
        check_positive("HFIPulsating.bandpass_bandwidth", self.bandpass_bandwidth, "rad/s")
        check_positive("HFIPulsating.error_cutoff", self.error_cutoff, "rad/s")
        hs.check_salient("HFIPulsating", self.L_d, self.L_q)

    def check_period(self, Ts: float) -> None:
        hs.check_carrier("HFIPulsating", self.hf_omega, self.bandpass_bandwidth, Ts)
        self.pll.check_period(Ts, "HFIPulsating.pll")

    def init(self, sample: Sample) -> HFIPulsatingState:
        dtype = sample.i_ab.dtype
        zero = jnp.zeros((), dtype)
        return HFIPulsatingState(
            zero, hs.bandpass_init(dtype), zero, PLL.init(jnp.asarray(self.theta0, dtype), zero)
        )

    def error_amplitude(self, Ts: float) -> Array:
        """The model's ``I_n``, A: the demodulated error is ``I_n sin(2 dth)``."""
        return hs.negative_sequence_amplitude(self.L_d, self.L_q, self.hf_voltage, self.hf_omega, Ts)

    def step(self, state: HFIPulsatingState, sample: Sample, Ts: float) -> tuple[HFIPulsatingState, Estimate]:
        coefficients = hs.bandpass_coefficients(self.hf_omega, self.bandpass_bandwidth, Ts)
        bandpass, i_h = hs.bandpass_step(state.bandpass, sample.i_ab, coefficients)
        theta_pred = PLL.predict(state.pll, Ts)
        omega_e = state.pll.omega
        # the resonator turns the pulsating vector by s when the frame rotates at w_e
        rotation = 0.5 * (
            hs.bandpass_phase(self.hf_omega + omega_e, coefficients, Ts)
            - hs.bandpass_phase(self.hf_omega - omega_e, coefficients, Ts)
        )
        i_qh = park(i_h, theta_pred + rotation)[1]
        phi = hs.flux_phase(state.carrier, self.hf_omega, Ts, self.delay_periods)
        demodulated = 2.0 * jnp.cos(phi) * i_qh  # I_n sin(2 dth) (1 + cos 2 phi)
        error = state.error + hs.lowpass_gain(self.error_cutoff, Ts) * (demodulated - state.error)
        pll_state = self.pll.correct(state.pll, theta_pred, error / (2.0 * self.error_amplitude(Ts)), Ts)
        u_inj = inverse_park(
            jnp.stack([self.hf_voltage * jnp.cos(state.carrier), jnp.zeros_like(error)]), pll_state.theta
        )
        carrier = wrap_angle(state.carrier + self.hf_omega * Ts)
        i_fund = sample.i_ab - i_h if self.filter_feedback else None
        return HFIPulsatingState(carrier, bandpass, error, pll_state), Estimate(
            pll_state.theta, pll_state.omega / self.pole_pairs, u_injection_ab=u_inj, i_ab_fundamental=i_fund
        )


def hfi_pulsating_design(
    motor: PMSMParameters,
    Ts: float,
    *,
    hf_voltage: float | None = None,
    hf_frequency: float | None = None,
    bandpass_q: float = hs.BANDPASS_Q,
    error_cutoff: float | None = None,
    pll_bandwidth: float | None = None,
    theta0: float = 0.0,
    delay_periods: float = 1.5,
    filter_feedback: bool = True,
) -> HFIPulsating:
    """The pulsating-injection estimator for ``motor`` at period ``Ts`` (s) by the design rule of the
    module docstring. ``hf_frequency`` in Hz (default ``0.1 / Ts``), ``hf_voltage`` in V (default: the
    voltage giving a 0.25 A error-signal amplitude), cut-offs and bandwidths in rad/s."""
    return HFIPulsating(
        **hs.injection_design(
            "hfi-pulsating",
            motor,
            Ts,
            hf_frequency=hf_frequency,
            hf_voltage=hf_voltage,
            bandpass_q=bandpass_q,
            error_cutoff=error_cutoff,
            pll_bandwidth=pll_bandwidth,
            theta0=theta0,
            delay_periods=delay_periods,
            filter_feedback=filter_feedback,
        )
    )
