"""Classic sliding-mode observer in the stationary frame (the book, ch. 5): ``smo`` (angle by arctan)
and ``smo-pll`` (angle by a PLL).

Equations (book; Chi, Zhang, Xu, "Sliding-mode sensorless control of direct-drive PM synchronous motors
for washing machine applications", IEEE TIA 45(2), 2009, doi:10.1109/TIA.2009.2013545)::

    L di^/dt = -R i^ + u - z,     z = k F(i^ - i)           (current observer, F: sign/saturation/sigmoid)
    e^ = LPF(z)                                              (back-EMF, cut-off w_c)
    th^ = -atan2(e^_a, e^_b) + lag(w^)                       (arctan; book: lag = atan(w^/w_c))
      or a PLL on -e_a cos th^ - e_b sin th^, plus lag(w^)   (pmsmjax.estimators.pll)

Sampled form (module docstring of [`stator_model`][pmsmjax.estimators.stator_model]): the current observer is
propagated exactly over the period with the held voltage and last period's ``z``,
``i^_k = Phi i^_{k-1} + Gamma (u_{k-1} - z_{k-1})``, then ``z_k = k F(i^_k - i_k)``. In the linear zone of a
smoothed ``F`` (gain ``G = k / width``) the error ``i^ - i`` obeys ``x_k = p x_{k-1} + Gamma (e_bar - z)``
with ``p = Phi - Gamma G``, so ``z`` is the back-EMF through the filter ``G Gamma W / (1 - p z^-1)``. The
angle is compensated with the *whole* chain's phase at the estimated speed, exactly for the sampled
filters: the period weighting ``W`` (about half a period,
[`stator_model.period_weight_phase`][pmsmjax.estimators.stator_model.period_weight_phase]), the observer pole
``p`` and the low-pass filter's pole ``exp(-w_c Ts)``
([`stator_model.first_order_lag`][pmsmjax.estimators.stator_model.first_order_lag]; it tends to the book's
``atan(w/w_c)`` as ``Ts -> 0``). For ``F = sign`` the chain is taken as deadbeat (``p = 0``: the switching
output's average is the last period's back-EMF).

Speed (``smo``): the rotation of ``e^`` between samples, ``atan2(e_{k-1} x e_k, e_{k-1} . e_k) / Ts``,
through a first-order filter of bandwidth ``speed_bandwidth``; its sign also tells which of the two
angles the back-EMF allows is meant. ``smo-pll``: the PLL's speed.

Design rule ([`smo_design`][pmsmjax.estimators.smo.smo_design]): ``k = k_margin psi_f w_e,max``
(``k > max|e|``, the sliding condition, with a margin; Utkin, Guldner, Shi, *Sliding Mode Control in
Electro-Mechanical Systems*, 2nd ed., 2009, ch. 10); ``width`` such that the linear-zone pole is ``p = pole``
(``G = (Phi - p)/Gamma``; ``p = 0`` would be deadbeat); ``w_c`` and the speed/PLL bandwidths are fixed values
chosen for 10 kHz sampling and 0.5 % measurement noise (see
[`smo_design`][pmsmjax.estimators.smo.smo_design]). ``check_period`` refuses ``|p| >= 1`` (``G`` above
``(1 + Phi)/Gamma``, about ``2 L / Ts``: 105 V/A on the book motor at 10 kHz) and unstable PLL gains.

Why the smoothed function is the default: the sign observer's current jumps by ``k Ts / L`` each period
(13 A for the design-rule ``k`` = 689 V on the book motor at 10 kHz, 3.5 A even for ``k`` = 184 V, 1.2
times the back-EMF at 2000 r/min), so its back-EMF estimate is a square wave of amplitude ``k`` that the
low-pass filter cannot clean: 50-94 electrical degrees RMS with the rule's ``k``, 11 with the small one,
against 0.25-0.5 for the sigmoid (benchmarks/observer_accuracy.py). With the smoothed function and the
rule's width the observer never leaves its linear zone: at this sample time it is a (saturating) linear
back-EMF observer. The margin of 3 keeps the per-axis sigmoid's compression of a rotating error small
(it lowers the effective gain, so the compensated lag is short: a margin of 1.5 left 0.45 degrees at
2000 r/min).
"""

import dataclasses
from typing import Literal

import equinox as eqx
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.estimators.base import AbstractModelObserver
from pmsmjax.estimators.pll import PLL, PLLState, pll_design
from pmsmjax.estimators.stability import check_loop, concrete_values
from pmsmjax.estimators.stator_model import (
    cross,
    emf_angle,
    first_order_lag,
    period_weight_phase,
    phase_detector,
    rl_coefficients,
    rotate,
    rotor_angle,
    safe_atan2,
)
from pmsmjax.estimators.switching import SWITCHING, Switching, linear_gain, switching_function
from pmsmjax.frames.three_phase import wrap_angle
from pmsmjax.machines.motor import PMSMParameters, as_float
from pmsmjax.signals import Estimate, Sample
from pmsmjax.spec.validation import ParameterError, check_choice, check_positive
from pmsmjax.units import rpm_to_rad_s

AngleMethod = Literal["arctan", "pll"]


def sliding_current_update(i_hat, z_prev, i_meas, u_drive, phi, gamma, k, width, switching: Switching):
    """One period of the sliding-mode current observer: ``(i^_k, z_k)``.

    ``i^_k = phi i^_{k-1} + gamma (u_drive - z_{k-1})`` (``u_drive``: ``(2,)`` V, the held voltage less any
    modelled coupling), ``z_k = k F(i^_k - i_k)``. Shared by the stationary- and rotating-frame observers.
    """
    i_hat = phi * i_hat + gamma * (u_drive - z_prev)
    return i_hat, k * switching_function(i_hat - i_meas, width, switching)


def observer_pole(phi, gamma, k, width, switching: Switching):
    """Linear-zone pole ``p = Phi - Gamma k / width`` of the current observer (0 for ``"sign"``)."""
    g = linear_gain(k, width, switching)
    return jnp.zeros_like(phi) if g is None else phi - gamma * g


def check_observer_pole(owner: str, R, L, k, width, switching: Switching, Ts: float) -> None:
    """Refuse a smoothed switching function whose linear zone is unstable at ``Ts`` (``|p| >= 1``)."""
    if switching == "sign":
        return  # no linear zone: the sign observer chatters with amplitude k Ts / L but does not diverge
    values = concrete_values(R, L, k, width)
    if values is None:
        return
    R, L, k, width = values

    def pole(r, ell, kk, w):
        phi, gamma = rl_coefficients(r, ell, Ts)
        return [[float(phi) - float(gamma) * kk / w]]

    phi, gamma = (float(x.max()) for x in rl_coefficients(R, L, Ts))
    g_max = (1 + phi) / gamma
    check_loop(
        f"{owner} current observer (linear-zone gain k/width = {float((k / width).max()):g} V/A)",
        pole,
        [R, L, k, width],
        f"widen the switching function: k/width must stay below (1 + Phi)/Gamma = {g_max:.4g} V/A (about "
        f"2 L/Ts); width >= {float(k.max()) / g_max:.4g} A for k = {float(k.max()):g} V",
    )


class AbstractSlidingModeObserver(AbstractModelObserver):
    """A chapter 5 sliding-mode observer: the sliding current model of
    [`sliding_current_update`][pmsmjax.estimators.smo.sliding_current_update] with the switching amplitude
    ``k`` (V), the switching-function width ``width`` (A) and the static ``switching`` function, in the
    stationary or the rotating frame."""

    k: eqx.AbstractVar[Array]
    width: eqx.AbstractVar[Array]
    switching: eqx.AbstractVar[Switching]

    def check_switching(self) -> None:
        """Raise unless the switching function, ``k`` and ``width`` are valid (the subclasses' checks)."""
        name = type(self).__name__
        check_choice(f"{name}.switching", self.switching, SWITCHING)
        check_positive(f"{name}.k (switching amplitude)", self.k, "V")
        check_positive(f"{name}.width (switching-function width)", self.width, "A")

    def sliding_update(self, state, i_meas, u_drive, L, Ts: float):
        """``(i^_k, z_k)`` of [`sliding_current_update`][pmsmjax.estimators.smo.sliding_current_update] from
        ``state.i_hat`` and ``state.z``, the measured current ``i_meas`` (A), the voltage ``u_drive`` (V) and
        the model's ``R`` with the inductance ``L`` (H) over the period ``Ts`` (s)."""
        phi, gamma = rl_coefficients(self.model.R, L, Ts)
        return sliding_current_update(
            state.i_hat, state.z, i_meas, u_drive, phi, gamma, self.k, self.width, self.switching
        )


class SMOState(eqx.Module):
    i_hat: Array  # (2,) A, observer current at the last sampling instant
    z: Array  # (2,) V, switching output of the last sampling instant
    emf: Array  # (2,) V, low-pass filtered back-EMF
    theta: Array  # rad, rotor angle ("arctan"); the filtered back-EMF's angle tracked by the PLL ("pll")
    omega: Array  # rad/s, electrical speed estimate (the PLL's speed for "pll")


class SlidingModeObserver(AbstractSlidingModeObserver):
    """Classic stationary-frame SMO (see the module docstring).

    **Arguments:**

    - `model`: the observer's motor model (``R``, ``L_q`` used as ``L``, ``psi_f``, ``pole_pairs``); may
      differ from the plant.
    - `k`: switching amplitude, V (must exceed the largest back-EMF).
    - `width`: width of the saturation/sigmoid function, A (unused by ``"sign"``).
    - `omega_c`: back-EMF low-pass cut-off, rad/s.
    - `speed_bandwidth`: bandwidth of the speed filter, rad/s (``angle="arctan"``; ``None`` for ``"pll"``).
    - `pll`: the PLL (``angle="pll"``; ``None`` for ``"arctan"``).
    - `emf_floor`: back-EMF floor of the PLL's phase-detector normalisation, V (``"pll"``).
    - `switching`: ``"sigmoid"`` (default), ``"saturation"`` or ``"sign"`` (static).
    - `angle`: ``"arctan"`` or ``"pll"`` (static).
    - `half_sample`: compensate the period weighting of the held voltage (static, default ``True``);
      ``False`` reproduces the common omission (about ``omega_e Ts / 2`` of angle error).
    """

    model: PMSMParameters
    k: Array = eqx.field(converter=as_float)
    width: Array = eqx.field(converter=as_float)
    omega_c: Array = eqx.field(converter=as_float)
    # an array when given (like every gain: tunable, vmappable; pmsmjax tune --estimator tunes it)
    speed_bandwidth: Array | None = eqx.field(
        default=None, converter=lambda x: None if x is None else as_float(x)
    )
    pll: PLL | None = None
    emf_floor: Array | None = None
    switching: Switching = eqx.field(static=True, default="sigmoid")
    angle: AngleMethod = eqx.field(static=True, default="arctan")
    half_sample: bool = eqx.field(static=True, default=True)

    def __check_init__(self):
        self.check_switching()
        check_choice("SlidingModeObserver.angle", self.angle, ("arctan", "pll"))
        check_positive("SlidingModeObserver.omega_c (back-EMF low-pass cut-off)", self.omega_c, "rad/s")
        if self.angle == "arctan":
            if self.speed_bandwidth is None:
                raise ParameterError("SlidingModeObserver with angle='arctan' needs speed_bandwidth (rad/s).")
            check_positive("SlidingModeObserver.speed_bandwidth", self.speed_bandwidth, "rad/s")
        else:
            if self.pll is None or self.emf_floor is None:
                raise ParameterError("SlidingModeObserver with angle='pll' needs pll and emf_floor (V).")
            check_positive("SlidingModeObserver.emf_floor", self.emf_floor, "V")

    def check_period(self, Ts: float) -> None:
        m = self.model
        check_observer_pole("SlidingModeObserver", m.R, m.L_q, self.k, self.width, self.switching, Ts)
        if self.pll is not None:
            self.pll.check_period(Ts, "SlidingModeObserver.pll")

    def chain_lag(self, omega_e, Ts: float):
        """Phase (rad) of the estimated back-EMF ``e^`` behind the true one at the sampling instant, for
        electrical speed ``omega_e`` (rad/s): period weighting, observer pole, low-pass pole."""
        m = self.model
        phi, gamma = rl_coefficients(m.R, m.L_q, Ts)
        p = observer_pole(phi, gamma, self.k, self.width, self.switching)
        lag = first_order_lag(omega_e, p, Ts) + first_order_lag(omega_e, jnp.exp(-self.omega_c * Ts), Ts)
        return lag + period_weight_phase(omega_e, m.R, m.L_q, Ts) if self.half_sample else lag

    def init(self, sample: Sample) -> SMOState:
        zero = jnp.zeros((), sample.i_ab.dtype)
        return SMOState(sample.i_ab, jnp.zeros_like(sample.i_ab), jnp.zeros_like(sample.i_ab), zero, zero)

    def step(self, state: SMOState, sample: Sample, Ts: float):
        m = self.model
        i_hat, z = self.sliding_update(state, sample.i_ab, sample.u_ab_last, m.L_q, Ts)
        emf = state.emf - jnp.expm1(-self.omega_c * Ts) * (z - state.emf)
        if self.angle == "arctan":
            rotation = safe_atan2(cross(state.emf, emf), jnp.dot(state.emf, emf)) / Ts
            omega = state.omega - jnp.expm1(-self.speed_bandwidth * Ts) * (rotation - state.omega)
            lag = self.chain_lag(omega, Ts)
            theta = wrap_angle(emf_angle(emf, omega) + lag)
        else:
            # The PLL tracks the filtered back-EMF's angle (theta here); the chain's lag is added to its
            # output, outside its loop (inside, the lag computed from the PLL's own speed would feed the
            # speed back into the phase error and shrink the stable gains several-fold).
            phi_pred = PLL.predict(PLLState(state.theta, state.omega), Ts)
            error = phase_detector(emf, phi_pred, self.emf_floor)
            pll_state = self.pll.correct(PLLState(state.theta, state.omega), phi_pred, error, Ts)
            theta, omega = pll_state.theta, pll_state.omega
            lag = self.chain_lag(omega, Ts)
        new_state = SMOState(i_hat, z, emf, theta, omega)
        rotor = theta if self.angle == "arctan" else wrap_angle(rotor_angle(theta + lag, omega))
        estimate = Estimate(rotor, omega / m.pole_pairs, back_emf_ab=rotate(emf, lag))
        return new_state, estimate

    def pull(self, state: SMOState, estimate: Estimate, theta_e, omega_m, strength) -> SMOState:
        """With ``angle="pll"``: the PLL's angle and speed moved by the estimate's distance to the target (it
        tracks the back-EMF's angle, the rotor angle plus pi below zero speed: the same increment). The
        ``"arctan"`` angle is the back-EMF's own, with no state to move: it runs free."""
        if self.angle != "pll":
            return state
        d_theta = strength * wrap_angle(theta_e - estimate.theta_e)
        d_omega = strength * (omega_m - estimate.omega_m)
        theta = wrap_angle(state.theta + d_theta)
        omega = state.omega + self.model.pole_pairs * d_omega
        return dataclasses.replace(state, theta=theta, omega=omega)


#: Design-rule defaults of [`smo_design`][pmsmjax.estimators.smo.smo_design] (see there for why).
SMO_MAX_SPEED_RPM = 3000.0
SMO_K_MARGIN = 3.0
SMO_POLE = 0.5
SMO_OMEGA_C = 2000.0
SMO_SPEED_BANDWIDTH = 500.0
SMO_PLL_BANDWIDTH = 1000.0
SMO_EMF_FLOOR_FRACTION = 0.02


def sliding_gains(model: PMSMParameters, L, Ts: float, max_speed_rpm, k_margin, pole):
    """The sliding current observer's design rule (the book, ch. 5), shared by the three sliding-mode
    observers: ``k = k_margin psi_f p_n w_max`` (V) above the largest back-EMF at ``max_speed_rpm``, and
    ``width = k Gamma / (Phi - pole)`` (A), the switching function's linear zone putting the sampled
    observer's pole at ``pole``, with the winding coefficients of ``model.R`` and ``L`` (H) over ``Ts`` (s).

    Returns:
        ``(k V, width A, w_max electrical rad/s)``.
    """
    check_positive("Ts (control period)", Ts, "s")
    check_positive("max_speed_rpm", max_speed_rpm, "r/min")
    check_positive("k_margin", k_margin)
    if not -1.0 < float(pole) < 1.0:
        raise ParameterError(f"pole must lie in (-1, 1) (the observer's sampled pole), got {pole!r}.")
    w_max = model.pole_pairs * rpm_to_rad_s(max_speed_rpm)
    k = k_margin * model.psi_f * w_max
    phi, gamma = rl_coefficients(model.R, L, Ts)
    return k, k * gamma / (phi - pole), w_max


def smo_design(
    motor: PMSMParameters,
    Ts: float,
    *,
    angle: AngleMethod = "arctan",
    switching: Switching = "sigmoid",
    max_speed_rpm: float = SMO_MAX_SPEED_RPM,
    k_margin: float = SMO_K_MARGIN,
    pole: float = SMO_POLE,
    omega_c: float = SMO_OMEGA_C,
    speed_bandwidth: float = SMO_SPEED_BANDWIDTH,
    pll_bandwidth: float = SMO_PLL_BANDWIDTH,
    emf_floor_fraction: float = SMO_EMF_FLOOR_FRACTION,
    model: PMSMParameters | None = None,
) -> SlidingModeObserver:
    """The classic SMO with design-rule gains for ``motor`` at period ``Ts`` (s).

    - ``k = k_margin psi_f p_n w_max`` (V), ``w_max`` = ``max_speed_rpm`` (689 V on the book motor at the
      default 3000 r/min and margin 3: the sigmoid's zone stays nearly linear up to 2000 r/min).
    - ``width = k Gamma / (Phi - pole)`` (A): the linear-zone pole at ``pole`` (0.5 by default: half the
      error left after a period, between deadbeat's noise gain (``pole`` 0) and a slow observer's lag).
    - ``omega_c`` (rad/s): the low-pass lag is compensated exactly, so it trades noise against the effect
      of speed-estimate errors on the compensation; ``speed_bandwidth`` (rad/s, ``"arctan"``: a slower
      filter lags the load step's speed dip, and the compensation with it); ``pll_bandwidth`` (rad/s,
      ``"pll"``, [`pmsmjax.estimators.pll.pll_design`][pmsmjax.estimators.pll.pll_design]: a type-2 loop's
      error under acceleration falls as 1/bw^2). Each default was chosen on the design-sensitivity table of
      benchmarks/observer_accuracy.py (book drive logs, 0.5 % noise; README.md).
    - ``emf_floor = emf_floor_fraction psi_f p_n w_max`` (V): the PLL's detector normalisation floor.

    `model`: the observer's motor model (default ``motor``: no mismatch).
    """
    model = motor if model is None else model
    k, width, w_max = sliding_gains(model, model.L_q, Ts, max_speed_rpm, k_margin, pole)
    tracker = (
        dict(speed_bandwidth=speed_bandwidth)
        if angle == "arctan"
        else dict(pll=pll_design(pll_bandwidth), emf_floor=emf_floor_fraction * model.psi_f * w_max)
    )
    return SlidingModeObserver(model, k, width, omega_c, switching=switching, angle=angle, **tracker)
