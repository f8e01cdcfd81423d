"""Rotating high-frequency injection (the book, ch. 6): the rotor angle modulo pi and the speed from the
saliency, at standstill and low speed.

Injection: ``u_ab,h = V_h [cos w_h t, sin w_h t]`` added to the controller's command (``u_injection_ab``,
sampled at the period start, held by the drive). The salient machine answers with a positive-sequence
current ``I_p e^{j phi}`` and a negative-sequence current ``I_n e^{j (2 th - phi)}``, ``phi`` the HF flux
phase ([`hfi_signal`][pmsmjax.estimators.hfi_signal], where ``I_n = (L_q - L_d) V_h / (2 L_d L_q w_eff)`` is
derived).

Signal chain per sample ``k`` (complex notation ``x_a + j x_b``):

1. **band-pass** ``i_h = BPF(i_ab)`` (resonator at ``w_h``, bandwidth ``B``); ``i_ab - i_h`` (the notch) is
   the fundamental current the controller gets (``Estimate.i_ab_fundamental``);
2. **negative-sequence extraction**: in the frame turning with the carrier the positive sequence is DC:
   ``p = LPF_{w_p}(i_h e^{-j phi})``, ``i_n = i_h - p e^{j phi}``;
3. **heterodyne demodulation**: ``z = i_n e^{j phi} = I_n e^{j 2 th}`` (exactly, at standstill);
   ``eps = Im(z e^{-j 2 th^}) = I_n sin(2 (th - th^))``, low-passed (cut-off ``w_l``, inside the loop so it
   costs no steady-state lag) and scaled by ``1 / (2 I_n)`` of the model: ``~ th - th^`` for small errors;
4. **PLL** ([`pmsmjax.estimators.pll.PLL`][pmsmjax.estimators.pll.PLL], type 2) -> ``th^``, ``w^``.

The resonator and the sequence filter delay the rotor's image, which turns at ``2 w_e`` (``w_e`` the
electrical speed): it sits at ``-(w_h - 2 w_e)`` in the stationary frame, where the resonator shifts it
by ``-arg H(w_h - 2 w_e)`` (``~ -4 w_e / B``), and the sequence filter's complement shifts it by
[`hfi_signal.highpass_complement_phase`][pmsmjax.estimators.hfi_signal.highpass_complement_phase]. The PLL
locks onto ``2 th`` less these; half of them, evaluated exactly at the PLL's speed, is added to its output
angle (not to the angle it locks to, see [`pll`][pmsmjax.estimators.pll]). The resistance, neglected in the HF
model, turns the negative sequence too: with the admittances ``1 / (R + j w L)`` in place of ``1 / (j w L)``
the image ``(Y_d - Y_q) / 2`` is turned by ``atan(R / (w L_d)) + atan(R / (w L_q))`` (2.4 degrees on the
salient book motor at 1 kHz, i.e. a 1.2 degree angle bias, measured 1.15 degrees before compensation); half of
it is added too.

Carrier phase: ``"internal"`` uses the estimator's own carrier and the drive's known delay
(``delay_periods``: 1.5 with a computational delay, 0.5 without); ``"measured"`` takes it from the
band-passed voltage applied over the last period (``u_ab_last``), for logs whose carrier started
elsewhere (``pmsmjax observe``): the flux at ``t_k`` leads that voltage's phase by ``x/2 - pi/2``.

Filter design ([`hfi_rotating_design`][pmsmjax.estimators.hfi_rotating.hfi_rotating_design]; defaults for the
book's 10 kHz control): ``f_h = f_s / 10`` (1 kHz: 10 samples a carrier period, Nyquist 5 kHz, 6x the 175 Hz
current-loop bandwidth); ``B = w_h / 5`` (1257 rad/s, second order); ``w_p = w_h / 50`` (126 rad/s, first
order: the positive sequence is constant at standstill, its 2 w_h image in the error is removed, not
filtered); ``w_l = w_h / 3`` (2094 rad/s, first order: attenuates what is left at ``2 w_h`` 6-fold); PLL
bandwidth ``w_l / 7`` (299 rad/s, double pole; the continuous loop with the in-loop low-pass is stable
for a bandwidth below ``2 w_l`` by Routh, and a seventh keeps its damping). Measured on the salient book
drive (speed-loop bandwidth 50 rad/s): a PLL bandwidth of 105 rad/s, twice the speed loop's, let the
speed loop and the estimator oscillate and lose lock under a 10 N m load at standstill; 200-300 rad/s
hold it (README.md).
``V_h`` such that ``I_n = 0.25 A`` (30 V on the salient book motor). The angle is modulo pi: the
estimator starts at ``theta0`` and locks to the d axis within +-90 degrees of it.

Reference: M. J. Corley, R. D. Lorenz, "Rotor position and velocity estimation for a salient-pole
permanent magnet synchronous machine at standstill and high speeds", IEEE TIA 34(4), 1998,
doi:10.1109/28.703964 (heterodyne demodulation of the negative sequence).
"""

from typing import ClassVar, Literal

import equinox as eqx
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.estimators import hfi_signal as hs
from pmsmjax.estimators.pll import PLL, AbstractPLLEstimator, PLLState
from pmsmjax.frames.three_phase import wrap_angle
from pmsmjax.machines.motor import PMSMParameters, as_float
from pmsmjax.signals import Estimate, Sample
from pmsmjax.spec.validation import ParameterError, check_positive

CarrierSource = Literal["internal", "measured"]


class HFIRotatingState(eqx.Module):
    carrier: Array  # rad, phase of this sample's carrier command (wrapped)
    bandpass: hs.BandpassState  # current resonator
    voltage_bandpass: hs.BandpassState | None  # voltage resonator ("measured" carrier only)
    positive: Array  # (2,) A, positive-sequence phasor (carrier frame), low-passed
    error: Array  # A, low-passed heterodyne error I_n sin(2 dth)
    pll: PLLState


class HFIRotating(AbstractPLLEstimator):
    """Rotating-injection estimator (see the module docstring).

    **Arguments:**

    - `L_d`, `L_q`: the model's inductances, H (scale the error signal; ``L_q > L_d``).
    - `R`: the model's stator resistance, ohm (its phase shift of the negative sequence is compensated).
    - `pole_pairs`: static int (electrical -> mechanical speed).
    - `hf_voltage`: carrier amplitude ``V_h``, V.
    - `hf_omega`: carrier angular frequency ``w_h``, rad/s.
    - `bandpass_bandwidth`: resonator -3 dB bandwidth ``B``, rad/s.
    - `sequence_cutoff`: positive-sequence low-pass cut-off ``w_p``, rad/s.
    - `error_cutoff`: error-signal low-pass cut-off ``w_l``, rad/s.
    - `pll`: the tracking loop (gains 1/s, 1/s^2).
    - `theta0`: initial angle estimate, electrical rad.
    - `delay_periods`: static, periods from the carrier command to the middle of its hold (1.5 with the
      drive's computational delay, 0.5 without).
    - `carrier`: static, ``"internal"`` or ``"measured"`` (module docstring).
    - `filter_feedback`: static; give the controller the notch-filtered current (default) or the raw one
      (for showing what the carrier does to the current loop).
    """

    injects_voltage: ClassVar[bool] = True

    L_d: Array = eqx.field(converter=as_float)
    L_q: Array = eqx.field(converter=as_float)
    R: Array = eqx.field(converter=as_float)
    pole_pairs: int = eqx.field(static=True)
    hf_voltage: Array = eqx.field(converter=as_float)
    hf_omega: Array = eqx.field(converter=as_float)
    bandpass_bandwidth: Array = eqx.field(converter=as_float)
    sequence_cutoff: Array = eqx.field(converter=as_float)
    error_cutoff: Array = eqx.field(converter=as_float)
    pll: PLL
    theta0: Array = eqx.field(converter=as_float, default=0.0)
    delay_periods: float = eqx.field(static=True, default=1.5)
    carrier: CarrierSource = eqx.field(static=True, default="internal")
    filter_feedback: bool = eqx.field(static=True, default=True)

    def __check_init__(self):
        check_positive("HFIRotating.hf_voltage", self.hf_voltage, "V")
        check_positive("HFIRotating.hf_omega", self.hf_omega, "rad/s")
        check_positive("HFIRotating.bandpass_bandwidth", self.bandpass_bandwidth, "rad/s")
        check_positive("HFIRotating.sequence_cutoff", self.sequence_cutoff, "rad/s")
        check_positive("HFIRotating.error_cutoff", self.error_cutoff, "rad/s")
        hs.check_salient("HFIRotating", self.L_d, self.L_q)
        if self.carrier not in ("internal", "measured"):
            raise ParameterError(
                f"HFIRotating.carrier must be 'internal' or 'measured', got {self.carrier!r}."
            )

    def check_period(self, Ts: float) -> None:
        hs.check_carrier("HFIRotating", self.hf_omega, self.bandpass_bandwidth, Ts)
        self.pll.check_period(Ts, "HFIRotating.pll")

    def init(self, sample: Sample) -> HFIRotatingState:
        dtype = sample.i_ab.dtype
        zero = jnp.zeros((), dtype)
        bp = hs.bandpass_init(dtype)
        return HFIRotatingState(
            zero,
            bp,
            bp if self.carrier == "measured" else None,
            jnp.zeros(2, dtype),
            zero,
            PLL.init(jnp.asarray(self.theta0, dtype), zero),
        )

    def negative_sequence_amplitude(self, Ts: float) -> Array:
        """The model's ``I_n``, A
        ([`hfi_signal.negative_sequence_amplitude`][pmsmjax.estimators.hfi_signal.negative_sequence_amplitude])."""
        return hs.negative_sequence_amplitude(self.L_d, self.L_q, self.hf_voltage, self.hf_omega, Ts)

    def step(self, state: HFIRotatingState, sample: Sample, Ts: float) -> tuple[HFIRotatingState, Estimate]:
        coefficients = hs.bandpass_coefficients(self.hf_omega, self.bandpass_bandwidth, Ts)
        bandpass, i_h = hs.bandpass_step(state.bandpass, sample.i_ab, coefficients)
        voltage_bandpass = state.voltage_bandpass
        if self.carrier == "internal":
            ref = hs.unit(hs.flux_phase(state.carrier, self.hf_omega, Ts, self.delay_periods))
        else:
            voltage_bandpass, u_h = hs.bandpass_step(state.voltage_bandpass, sample.u_ab_last, coefficients)
            # the flux at t_k leads the last period's (held) voltage by x/2 - pi/2. Normalised to a unit
            # phasor so that a log's carrier amplitude only scales I_n; below 1 % of V_h (the resonator
            # starting) no reference. Double where: finite gradients at zero.
            mag2 = jnp.sum(u_h * u_h)
            present = mag2 > (0.01 * self.hf_voltage) ** 2
            u_unit = jnp.where(present, u_h / jnp.sqrt(jnp.where(present, mag2, 1.0)), 0.0)
            ref = hs.cmul(u_unit, hs.unit(0.5 * self.hf_omega * Ts - 0.5 * jnp.pi))
        # negative-sequence extraction: the positive sequence is DC in the carrier's frame
        g_p = hs.lowpass_gain(self.sequence_cutoff, Ts)
        positive = state.positive + g_p * (hs.cmul(i_h, hs.conj(ref)) - state.positive)
        i_n = i_h - hs.cmul(positive, ref)
        z = hs.cmul(i_n, ref)  # I_n e^{j 2 th} (less the filters' delay)
        # heterodyne against the PLL's prediction, low-pass inside the loop
        theta_pred = PLL.predict(state.pll, Ts)
        c2, s2 = jnp.cos(2.0 * theta_pred), jnp.sin(2.0 * theta_pred)
        eps = z[1] * c2 - z[0] * s2  # Im(z e^{-j 2 th^}) = I_n sin(2 (th - th^))
        error = state.error + hs.lowpass_gain(self.error_cutoff, Ts) * (eps - state.error)
        scale = 2.0 * self.negative_sequence_amplitude(Ts)
        pll_state = self.pll.correct(state.pll, theta_pred, error / scale, Ts)
        # the filters delay the image 2 th, turning at 2 w_e: add half their phase lag to the output
        omega_e = pll_state.omega
        lag_2th = hs.bandpass_phase(self.hf_omega - 2.0 * omega_e, coefficients, Ts)
        lag_2th = lag_2th - hs.highpass_complement_phase(-(2.0 * self.hf_omega - 2.0 * omega_e) * Ts, g_p)
        # the resistance turns the negative sequence by atan(R / (w L_d)) + atan(R / (w L_q))
        w_eff = hs.effective_frequency(self.hf_omega, Ts)
        lag_2th = lag_2th + jnp.arctan(self.R / (w_eff * self.L_d)) + jnp.arctan(self.R / (w_eff * self.L_q))
        theta = wrap_angle(pll_state.theta + 0.5 * lag_2th)
        u_inj = self.hf_voltage * hs.unit(state.carrier)
        carrier = wrap_angle(state.carrier + self.hf_omega * Ts)
        new_state = HFIRotatingState(carrier, bandpass, voltage_bandpass, positive, error, pll_state)
        i_fund = sample.i_ab - i_h if self.filter_feedback else None
        return new_state, Estimate(
            theta, omega_e / self.pole_pairs, u_injection_ab=u_inj, i_ab_fundamental=i_fund
        )


def hfi_rotating_design(
    motor: PMSMParameters,
    Ts: float,
    *,
    sequence_cutoff: float | None = None,
    carrier: str = "internal",
    hf_voltage: float | None = None,
    hf_frequency: float | None = None,
    bandpass_q: float = hs.BANDPASS_Q,
    error_cutoff: float | None = None,
    pll_bandwidth: float | None = None,
    theta0: float = 0.0,
    delay_periods: float = 1.5,
    filter_feedback: bool = True,
) -> HFIRotating:
    """The rotating-injection estimator for ``motor`` at period ``Ts`` (s) by the design rule of the
    module docstring. ``hf_frequency`` in Hz (default ``0.1 / Ts``), ``hf_voltage`` in V (default: the
    voltage giving a 0.25 A negative sequence), cut-offs and bandwidths in rad/s."""
    fields = hs.injection_design(
        "hfi-rotating",
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
    w_h = fields["hf_omega"]
    return HFIRotating(
        R=motor.R,
        sequence_cutoff=w_h / 50.0 if sequence_cutoff is None else sequence_cutoff,
        carrier=carrier,
        **fields,
    )
