"""The reduced-order stator-flux observer of Hinkkanen et al. on the machine's current-flux relation: a
sensorless observer that reads a measured flux map as directly as a linear model.

**Source.** M. Hinkkanen, S. E. Saarakkala, H. A. A. Awan, E. Molsa, T. Tuovinen, "Observers for sensorless
synchronous motor drives: framework for design and analysis", IEEE Trans. Ind. Appl. 54(6), 2018,
doi:10.1109/TIA.2018.2858753 (the gain that decouples flux and angle estimation, its error dynamics
``s^2 + 2 sigma s + w^2``). The auxiliary flux of a saturated machine is the one of the same framework
(the MTPA auxiliary flux below; motulator's observer documentation writes it in this form).

**Observer** (complex notation, estimated rotor coordinates at ``th^``, ``J`` = rotation by 90 degrees):

    dpsi^/dt = u - R i - j w_s psi^ + k1 e + k2 e*,     e = psi_i(i) - psi^
    dth^/dt  = w_s = w^ + k_th eps,     dw^/dt = k_w eps,     eps = -Im(e / psi_a)

``psi_i(i)`` is the current-flux relation: the drive file's flux map
([`FluxMap`][pmsmjax.machines.pmsm_flux_map.FluxMap], bicubic, differentiable), or for a linear machine
``[L_d i_d + psi_f, L_q i_q]``. ``psi_a`` is the auxiliary flux

    psi_a(i) = psi_i(i) - L_qq i_d - j L_dd i_q + j L_dq i*

with the incremental inductances ``L_xy = dpsi_x/di_y`` of the same relation (linear machine:
``psi_a = psi_f + (L_d - L_q) i*``). Why: the true flux seen in the estimated frame is, to first order in
the angle error ``th~ = th - th^``, ``psi = psi_i(i) + j th~ psi_a`` (differentiate ``e^{j th~}
psi_i(e^{-j th~} i)``), so ``e = psi~ - j th~ psi_a`` and ``eps = th~ - Im(psi~/psi_a)``: the angle error
once the flux error ``psi~ = psi - psi^`` has decayed.

**Gain** (Hinkkanen et al. 2018): ``k1 = sigma``, ``k2 = sigma psi_a / psi_a*``. Then
``k1 e + k2 e* = 2 sigma psi_a Re(e/psi_a)``, in which ``th~`` cancels: the flux estimation is decoupled
from the angle, and its linearised error obeys ``s^2 + 2 sigma s + w^2`` (``w`` electrical speed): stable
for every ``sigma > 0`` and ``w != 0``; at standstill one pole is at 0 (the flux along ``j psi_a``, which
is the angle, is not observable there: start with I/f or HF injection). ``sigma = sigma0 + zeta |w^|``
gives the damping ``zeta`` at high speed and the pole ``-2 sigma0`` at standstill (the scheduled form of
the paper's design). The angle loop ``th~ -> eps -> (k_th, k_w)`` is a type-2 PLL;
``k_th = 2 alpha``, ``k_w = alpha^2`` put its double pole at ``-alpha`` (``bandwidth``).

**Sampled form.** The flux is kept in the stationary frame (the ``-j w_s psi^`` term is the rotation of
the coordinates, exact there): over the period ending at ``t_k`` it integrates ``Ts (u_last - R
(i_{k-1} + i_k)/2)`` (the applied mean voltage, the trapezoid of the current), then the correction
``Ts (k1 e + k2 e*)`` is added in the frame predicted at ``t_k`` (``th- = th + Ts w^``), and the angle and
speed take ``Ts k_th eps`` and ``Ts k_w eps``. One period of the flux error is a rotation by ``w Ts`` and
a contraction ``1 - 2 sigma Ts`` along ``psi_a``: stable iff ``0 < sigma Ts < 1`` (checked at the highest
speed ``max_speed_rpm``), and the angle loop as every PLL here
([`pll`][pmsmjax.estimators.pll]: ``0 < Ts k_th < 2``, ``0 < Ts^2 k_w < 4 - 2 Ts k_th``).

**Verification.** tests/estimators/test_map_flux_observer.py: exact on a linear machine with its exact
model, the start from standstill to field weakening on two flux maps within 3 degrees and the current
limit, finite-difference gradients of the gains, the refusals.
"""

import dataclasses

import equinox as eqx
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.estimators.base import AbstractModelObserver
from pmsmjax.estimators.stability import check_loop, concrete_values, tracking_loop_matrix
from pmsmjax.frames.three_phase import inverse_park, park, wrap_angle
from pmsmjax.machines.motor import PMSMParameters, as_float
from pmsmjax.machines.pmsm_flux_map import FluxMap
from pmsmjax.signals import Estimate, Sample
from pmsmjax.spec.validation import ParameterError, check_nonnegative, check_positive
from pmsmjax.units import rpm_to_rad_s

__all__ = [
    "MapFluxObserver",
    "MapFluxObserverState",
    "auxiliary_flux",
    "current_flux",
    "flux_observer_design",
    "FLUX_OBSERVER_BANDWIDTH",
    "FLUX_OBSERVER_SIGMA0",
]

#: Flux-error attenuation at standstill of the design rule, rad/s (module docstring: a small value keeps the
#: slowest pole ``~ w^2 / (2 sigma)`` fast at low speed; benchmarks/map_observer_range.py).
FLUX_OBSERVER_SIGMA0 = 5.0
#: Angle-loop bandwidth ``alpha`` of the design rule
#: ([`flux_observer_design`][pmsmjax.estimators.map_flux_observer.flux_observer_design]), rad/s.
FLUX_OBSERVER_BANDWIDTH = 800.0


def current_flux(model: PMSMParameters, flux_map: FluxMap | None, i_dq: Array) -> tuple[Array, Array]:
    """``(psi (2,) Wb, L_inc (2, 2) H)`` of the current-flux relation at ``i_dq (2,)`` A: the map's, or the
    linear model's ``[L_d i_d + psi_f, L_q i_q]`` when ``flux_map`` is None."""
    if flux_map is not None:
        return flux_map(i_dq)
    psi = jnp.stack([model.L_d * i_dq[0] + model.psi_f, model.L_q * i_dq[1]])
    zero = jnp.zeros_like(model.L_d)
    return psi, jnp.stack([jnp.stack([model.L_d, zero]), jnp.stack([zero, model.L_q])])


def auxiliary_flux(psi: Array, L: Array, i_dq: Array) -> Array:
    """``psi_a = psi - L_qq i_d - j L_dd i_q + j L_dq i*`` ((2,) Wb, module docstring) from the flux
    ``psi (2,)`` Wb and incremental inductances ``L (2, 2)`` H (``L[x, y] = dpsi_x/di_y``) at ``i_dq (2,)``
    A. Written with each cross inductance where the angle derivative puts it (``L_qd`` in the d part,
    ``L_dq`` in the q part), so it is exact for a measured map that is not quite reciprocal."""
    return jnp.stack(
        [
            psi[0] - L[1, 1] * i_dq[0] + L[1, 0] * i_dq[1],
            psi[1] - L[0, 0] * i_dq[1] + L[0, 1] * i_dq[0],
        ]
    )


def _safe_norm2(a: Array) -> tuple[Array, Array]:
    """``(|a|^2 guarded, ok)``: the double-``where`` guard that keeps gradients finite at ``a = 0``."""
    n2 = a[0] * a[0] + a[1] * a[1]
    ok = n2 > 1e-12
    return jnp.where(ok, n2, 1.0), ok


class MapFluxObserverState(eqx.Module):
    psi_ab: Array  # (2,) Wb, stator flux estimate at the last sample, stationary frame
    theta: Array  # rad, electrical angle estimate at the last sample
    omega: Array  # rad/s, electrical speed estimate
    i_ab: Array  # (2,) A, the last current sample (trapezoid of R i; the pull's current model)


class MapFluxObserver(AbstractModelObserver):
    """Reduced-order flux observer with speed adaptation on the current-flux relation (module docstring).

    Args:
        model: The observer's motor model: ``R``, ``pole_pairs``, and ``L_d``, ``L_q``, ``psi_f`` when there
            is no map.
        sigma0: Flux-error attenuation at standstill, rad/s (``k1 = sigma0 + zeta |w^|``).
        zeta: Damping of the flux-error poles at high speed (dimensionless, >= 0).
        k_theta: Angle gain, 1/s (``2 alpha``).
        k_omega: Speed gain, 1/s^2 (``alpha^2``).
        flux_map: The machine's flux map, or None for the linear model.
        max_speed: Highest electrical speed the sampled flux loop is checked at, rad/s (static).
    """

    model: PMSMParameters
    sigma0: Array = eqx.field(converter=as_float)
    zeta: Array = eqx.field(converter=as_float)
    k_theta: Array = eqx.field(converter=as_float)
    k_omega: Array = eqx.field(converter=as_float)
    flux_map: FluxMap | None = None
    max_speed: float = eqx.field(static=True, default=0.0)

    def __check_init__(self):
        fix = f"the design rule gives sigma0 = {FLUX_OBSERVER_SIGMA0:g} rad/s"
        check_positive(
            "MapFluxObserver.sigma0 (flux-error attenuation at standstill)", self.sigma0, "rad/s", fix
        )
        check_nonnegative(
            "MapFluxObserver.zeta (flux-error damping at speed)", self.zeta, "", "give 0.2 to 1"
        )
        check_positive("MapFluxObserver.k_theta (angle gain)", self.k_theta, "1/s", "give 2 alpha")
        check_positive("MapFluxObserver.k_omega (speed gain)", self.k_omega, "1/s^2", "give alpha^2")

    def check_period(self, Ts: float) -> None:
        values = concrete_values(self.sigma0, self.zeta)
        if values is not None:
            worst = float((values[0] + values[1] * self.max_speed).max() * Ts)
            if not 0.0 < worst < 1.0:
                raise ParameterError(
                    f"MapFluxObserver flux gain (sigma0 + zeta w_max) Ts = {worst:.4g} at w_max = "
                    f"{self.max_speed:g} rad/s is unstable at this sample time (it must stay below 1): lower "
                    "sigma0 or zeta, or max_speed_rpm."
                )
        values = concrete_values(self.k_theta, self.k_omega)
        if values is not None:
            check_loop(
                f"MapFluxObserver angle loop (k_theta = {values[0].max():g} 1/s, k_omega = "
                f"{values[1].max():g} 1/s^2)",
                lambda a, b: tracking_loop_matrix(Ts * a, Ts * Ts * b),
                values,
                f"lower the bandwidth: k_theta = 2 alpha, k_omega = alpha^2 is stable for alpha < "
                f"{(8**0.5 - 2) / Ts:.4g} rad/s",
            )

    def with_flux_map(self, flux_map: FluxMap) -> "MapFluxObserver":
        """The same observer reading ``flux_map`` (the drive file's) instead of the linear model."""
        return dataclasses.replace(self, flux_map=flux_map)

    def flux(self, i_dq: Array) -> tuple[Array, Array]:
        """``(psi (2,) Wb, L_inc (2, 2) H)`` of the observer's current-flux relation at ``i_dq (2,)`` A."""
        return current_flux(self.model, self.flux_map, i_dq)

    def init(self, sample: Sample) -> MapFluxObserverState:
        zero = jnp.zeros((), sample.i_ab.dtype)
        psi, _ = self.flux(park(sample.i_ab, zero))
        return MapFluxObserverState(
            inverse_park(psi.astype(sample.i_ab.dtype), zero), zero, zero, sample.i_ab
        )

    def step(self, state: MapFluxObserverState, sample: Sample, Ts: float):
        m = self.model
        i_mean = 0.5 * (state.i_ab + sample.i_ab)
        psi_pred = state.psi_ab + Ts * (sample.u_ab_last - m.R * i_mean)
        theta_pred = state.theta + Ts * state.omega
        i_dq = park(sample.i_ab, theta_pred)
        psi_dq = park(psi_pred, theta_pred)
        psi_i, L = self.flux(i_dq)
        e = psi_i - psi_dq
        a = auxiliary_flux(psi_i, L, i_dq)
        n2, ok = _safe_norm2(a)
        eps = jnp.where(ok, -(e[1] * a[0] - e[0] * a[1]) / n2, 0.0)  # -Im(e / psi_a)
        along = jnp.where(ok, (e[0] * a[0] + e[1] * a[1]) / n2, 0.0)  # Re(e / psi_a)
        sigma = self.sigma0 + self.zeta * jnp.abs(state.omega)
        psi_dq = psi_dq + Ts * 2.0 * sigma * along * a  # k1 e + k2 e*
        theta = wrap_angle(theta_pred + Ts * self.k_theta * eps)
        omega = state.omega + Ts * self.k_omega * eps
        psi_ab = inverse_park(psi_dq, theta_pred)
        torque = 1.5 * m.pole_pairs * (psi_ab[0] * sample.i_ab[1] - psi_ab[1] * sample.i_ab[0])
        estimate = Estimate(theta, omega / m.pole_pairs, psi_ab=psi_ab, torque=torque)
        return MapFluxObserverState(psi_ab, theta, omega, sample.i_ab), estimate

    def pull(self, state: MapFluxObserverState, estimate: Estimate, theta_e, omega_m, strength):
        """Angle and speed moved by the estimate's distance to the target, and the flux ``strength`` of the
        way to the current-flux relation's flux in the target's frame (the flux along ``j psi_a`` is the
        angle, unobservable at standstill: it follows the angle it is slaved to)."""
        theta = wrap_angle(state.theta + strength * wrap_angle(theta_e - estimate.theta_e))
        omega = state.omega + strength * self.model.pole_pairs * (omega_m - estimate.omega_m)
        psi_i, _ = self.flux(park(state.i_ab, theta))
        psi_ab = state.psi_ab + strength * (inverse_park(psi_i, theta) - state.psi_ab)
        return MapFluxObserverState(psi_ab, theta, omega, state.i_ab)


def flux_observer_design(
    motor: PMSMParameters,
    Ts: float,
    *,
    bandwidth: float = FLUX_OBSERVER_BANDWIDTH,
    sigma0: float = FLUX_OBSERVER_SIGMA0,
    zeta: float = 0.5,
    max_speed_rpm: float = 6000.0,
    model: PMSMParameters | None = None,
    flux_map: FluxMap | None = None,
) -> MapFluxObserver:
    """The flux observer for ``motor`` (or ``model``) at period ``Ts`` (s): angle loop with a double pole at
    ``-bandwidth`` (rad/s: ``k_theta = 2 bw``, ``k_omega = bw^2``), flux attenuation ``sigma0 + zeta |w^|``
    (``sigma0`` rad/s: the standstill pole is ``-2 sigma0``, and at a low speed ``w << sigma`` the slowest
    flux-error pole is about ``-w^2 / (2 sigma)``, so a small ``sigma0`` is what makes the angle converge at
    low speed; ``zeta`` the damping at speed), its sampled flux loop checked up to
    ``max_speed_rpm`` (r/min); on ``flux_map`` when given (module docstring)."""
    check_positive("Ts (control period)", Ts, "s")
    check_positive("bandwidth (flux observer angle loop)", bandwidth, "rad/s")
    check_positive("max_speed_rpm (flux observer)", max_speed_rpm, "r/min")
    model = motor if model is None else model
    bw = as_float(bandwidth)
    w_max = rpm_to_rad_s(max_speed_rpm) * int(model.pole_pairs)
    return MapFluxObserver(model, sigma0, zeta, 2.0 * bw, bw * bw, flux_map, float(w_max))
