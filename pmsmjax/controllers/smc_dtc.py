"""Sliding-mode direct torque control with space-vector modulation (the book, ch. 4; the variable-structure
DTC of C. Lascu, I. Boldea and F. Blaabjerg, "Variable-structure direct torque control - a class of fast
and robust controllers for induction machine drives", IEEE Trans. Ind. Electron. 51(4), 785-792, 2004,
doi:10.1109/TIE.2004.831721; for the PMSM: Z. Xu and M. F. Rahman, "Direct torque and flux regulation of
an IPM synchronous motor drive using variable structure control approach", IEEE Trans. Power Electron.
22(6), 2487-2498, 2007).

**Theory.** In the frame of the stator flux ``psi = |psi| e^{j theta_psi}`` (x along it, y ahead of it by
90 deg), ``dpsi/dt = u - R i`` splits into

    d|psi|/dt = u_x - R i_x,        |psi| d(theta_psi)/dt = u_y - R i_y,

so ``u_x`` moves the flux magnitude and ``u_y`` the flux angle, hence the load angle and the torque
``T = 1.5 p_n |psi| i_y``. In steady state the flux turns at the rotor's electrical speed with a constant
magnitude, ``dpsi/dt = j omega_e psi``: the voltage that holds it there is exactly

    u_ff = R i + j omega_e psi        (stator frame; no inductance, no magnet flux)

and any departure from it moves the flux and the torque. For a surface machine
(``psi = L i + psi_f e^{j theta_e}``) the torque responds to ``v_y = u_y - u_ff,y`` as
``dT/dt = b_T v_y`` with ``b_T = 1.5 p_n psi_f cos(delta)/L`` (N m/(V s); ``delta`` the load angle), and
the flux magnitude to ``v_x`` as ``d|psi|/dt = v_x`` exactly.

**Control law.** Sliding surfaces on the errors, ``s_psi = psi* - |psi|`` (Wb) and ``s_T = T* - T`` (N m)
(relative degree one: the surface is the error); the correction voltages are

    v_x = K_psi f(s_psi / phi_psi),   v_y = K_T f(s_T / phi_T),
    u* = u_ff + v_x e^{j theta_psi} + v_y j e^{j theta_psi}

with switching function ``f`` (static ``switching``): ``"sign"`` (the pure sliding mode: ``v = +-K``
every period, chattering of ``b_T K_T Ts`` per period), ``"saturation"`` ``clip(s/phi, -1, 1)``
(boundary layer: linear with gain ``K/phi`` inside, ``+-K`` outside; the default) or ``"tanh"`` (the
smooth surrogate for gradients). Outside the layer the error falls at the
constant rate ``b_T K_T`` (torque) or ``K_psi`` (flux) whatever its size (the sliding condition
``s ds/dt < 0`` holds while ``K`` exceeds the disturbance); inside it the loop is first order with
bandwidth ``a_T = b_T K_T / phi_T`` and ``a_psi = K_psi / phi_psi`` (rad/s). The feed-forward makes the
steady state exact: ``v = 0`` holds it, so ``s = 0`` without an integral (with the exact models; a
resistance error ``dR`` leaves ``dR |i| / (K/phi)`` of error).

**Discrete implementation.** Once per PWM period, on the sampled current and the estimator's flux and
torque ([`pmsmjax.estimators.StatorFluxObserver`][pmsmjax.estimators.flux_observer.StatorFluxObserver]);
``u*`` is rotated by ``omega_e`` times the time from the sample to the middle of the period it acts in (half a
period, one more with a computational delay:
[`pmsmjax.controllers.current_pi.angle_lead`][pmsmjax.controllers.current_pi.angle_lead]), as the flux turns
that far meanwhile, limited to the modulator's linear range (direction kept) and applied by SVPWM: a constant
switching frequency, the PWM frequency. With the one-period delay the in-layer loop
``x[k+1] = x[k] - a Ts x[k-1]`` is stable for ``a Ts < 1`` and not oscillatory for ``a Ts <= 1/4``
([`smc_dtc_design`][pmsmjax.controllers.smc_dtc.smc_dtc_design] refuses ``a Ts >= 1/2``).

The speed loop and the torque reference are the table DTC's
(`pmsmjax.controllers.dtc.speed_torque_reference`: the speed block's current times ``K_t``).
"""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.controllers.base import AbstractSpeedController
from pmsmjax.controllers.current_pi import angle_lead
from pmsmjax.controllers.dtc import (
    AbstractTorqueCascade,
    DTCMode,
    check_flux_estimate,
    flux_magnitude,
    implied_current_reference,
    speed_torque_reference,
)
from pmsmjax.controllers.pi import clip_magnitude
from pmsmjax.controllers.smc import SWITCHING, Switching, switching_function
from pmsmjax.frames.three_phase import park, rotation
from pmsmjax.machines.motor import PMSMParameters, as_float
from pmsmjax.signals import CommandKind, ControlOutput, Estimate, References, Sample
from pmsmjax.spec.validation import ParameterError, check_choice, check_positive, is_concrete

__all__ = ["SlidingModeDTC", "SlidingModeDTCState", "smc_dtc_design"]


class SlidingModeDTCState(eqx.Module):
    speed: object  # the speed block's state
    torque_ref: Array  # N m, held between speed-loop updates
    counter: Array  # int32, periods since the last speed-loop update


class SlidingModeDTC(AbstractTorqueCascade):
    """Sliding-mode DTC: flux-frame voltage from sliding-mode laws on the flux and torque errors, for SVPWM.

    **Arguments:**

    - `model`: the controller's motor model (``R`` of the feed-forward, ``K_t``, the default flux
      reference and speed design).
    - `torque_gain_v`: ``K_T``, V: the switching gain of the torque channel (the y voltage outside the
      boundary layer).
    - `torque_boundary_nm`: ``phi_T``, N m: boundary-layer width of the torque surface (unused by
      ``"sign"``).
    - `flux_gain_v`: ``K_psi``, V. `flux_boundary_wb`: ``phi_psi``, Wb.
    - `current_limit`: peak phase-current limit, A (the torque reference is limited to what it allows at
      the flux reference:
      [`pmsmjax.controllers.dtc.torque_current_limit`][pmsmjax.controllers.dtc.torque_current_limit]).
    - `speed`: the speed block (output a current, A); ``None``: the PI with active damping at
      `speed_bandwidth` rad/s.
    - `flux_ref_wb`: ``psi*``, Wb; ``None`` takes ``model.psi_f``.
    - `switching`: ``"sign"``, ``"saturation"`` (default) or ``"tanh"`` (static).
    - `mode`: ``"speed"`` or ``"torque"`` (static); `speed_divider`: periods per speed-loop update
      (static).
    """

    command_kind: ClassVar[CommandKind] = "voltage"

    torque_gain_v: Array
    torque_boundary_nm: Array
    flux_gain_v: Array
    flux_boundary_wb: Array
    switching: Switching = eqx.field(static=True)

    def __init__(
        self,
        model: PMSMParameters,
        torque_gain_v,
        torque_boundary_nm,
        flux_gain_v,
        flux_boundary_wb,
        current_limit,
        speed: AbstractSpeedController | None = None,
        *,
        flux_ref_wb=None,
        switching: Switching = "saturation",
        mode: DTCMode = "speed",
        speed_divider: int = 1,
        speed_bandwidth=50.0,
    ):
        super().__init__(model, current_limit, speed, flux_ref_wb, mode, speed_divider, speed_bandwidth)
        self.torque_gain_v = as_float(torque_gain_v)
        self.torque_boundary_nm = as_float(torque_boundary_nm)
        self.flux_gain_v = as_float(flux_gain_v)
        self.flux_boundary_wb = as_float(flux_boundary_wb)
        self.switching = switching

    def __check_init__(self):
        check_choice("SlidingModeDTC.switching", self.switching, SWITCHING)
        for name, value, unit in (
            ("torque_gain_v (torque switching gain K_T)", self.torque_gain_v, "V"),
            ("torque_boundary_nm (torque boundary layer)", self.torque_boundary_nm, "N m"),
            ("flux_gain_v (flux switching gain K_psi)", self.flux_gain_v, "V"),
            ("flux_boundary_wb (flux boundary layer)", self.flux_boundary_wb, "Wb"),
        ):
            check_positive(f"SlidingModeDTC.{name}", value, unit)

    def init(self, dtype=None) -> SlidingModeDTCState:
        dtype = self.state_dtype(dtype)
        return SlidingModeDTCState(self.speed.init(dtype), jnp.zeros((), dtype), jnp.zeros((), jnp.int32))

    def step(
        self,
        state: SlidingModeDTCState,
        sample: Sample,
        estimate: Estimate,
        refs: References,
        Ts,
        u_max,
        delayed,
    ) -> tuple[SlidingModeDTCState, ControlOutput]:
        check_flux_estimate(type(self).__name__, sample, estimate)
        torque_ref, speed_state, counter = speed_torque_reference(self, state, estimate, refs, Ts)
        psi = estimate.psi_ab
        magnitude = flux_magnitude(psi)
        # Unit vector along the flux (guarded: the flux is never near zero in a PMSM, but the gradient
        # must stay finite).
        unit = psi / jnp.where(magnitude > 0, magnitude, 1.0)
        v_x = self.flux_gain_v * switching_function(
            self.flux_ref_wb - magnitude, self.flux_boundary_wb, self.switching
        )
        v_y = self.torque_gain_v * switching_function(
            torque_ref - estimate.torque, self.torque_boundary_nm, self.switching
        )
        omega_e = self.model.pole_pairs * estimate.omega_m
        quarter_turn = lambda x: jnp.stack([-x[1], x[0]])  # j x
        u = self.model.R * sample.i_ab + omega_e * quarter_turn(psi) + v_x * unit + v_y * quarter_turn(unit)
        u = rotation(omega_e * angle_lead(Ts, delayed)) @ u
        u_ab = clip_magnitude(u_max)(u)
        out = ControlOutput(u_ab, park(u_ab, estimate.theta_e), implied_current_reference(self, torque_ref))
        return SlidingModeDTCState(speed_state, torque_ref, counter), out


def smc_dtc_design(
    motor: PMSMParameters,
    *,
    torque_rate_nm_per_ms=10.0,
    flux_rate_wb_per_s=20.0,
    torque_bandwidth_rad_s=2000.0,
    flux_bandwidth_rad_s=2000.0,
    Ts=1e-4,
) -> dict:
    """Gains of [`SlidingModeDTC`][pmsmjax.controllers.smc_dtc.SlidingModeDTC] from the reaching rates and the
    in-layer bandwidths.

    **Arguments:**

    - `motor`: the controller's model (``b_T = K_t / L_q``, the torque channel's gain at zero load
      angle, N m/(V s)).
    - `torque_rate_nm_per_ms`: ``b_T K_T``, the torque slew outside the boundary layer, N m/ms (10: the
      rated 10 N m in 1 ms): ``K_T = rate / b_T`` (47.9 V on the book motor).
    - `flux_rate_wb_per_s`: ``K_psi``, the flux slew outside the layer, Wb/s (= V; 20 V moves the flux by
      11 % of psi_f in 1 ms).
    - `torque_bandwidth_rad_s`, `flux_bandwidth_rad_s`: ``a`` inside the layer, rad/s:
      ``phi_T = b_T K_T / a_T`` (5.0 N m) and ``phi_psi = K_psi / a_psi`` (10 mWb).
    - `Ts`: control period, s: ``a Ts < 1/2`` is required (the one-period delay; module docstring).

    **Returns:** the keyword arguments ``torque_gain_v, torque_boundary_nm, flux_gain_v,
    flux_boundary_wb`` of [`SlidingModeDTC`][pmsmjax.controllers.smc_dtc.SlidingModeDTC].
    """
    for name, value, unit in (
        ("torque_rate_nm_per_ms", torque_rate_nm_per_ms, "N m/ms"),
        ("flux_rate_wb_per_s", flux_rate_wb_per_s, "Wb/s"),
        ("torque_bandwidth_rad_s", torque_bandwidth_rad_s, "rad/s"),
        ("flux_bandwidth_rad_s", flux_bandwidth_rad_s, "rad/s"),
        ("Ts (control period)", Ts, "s"),
    ):
        check_positive(name, value, unit)
    for name, a in (("torque", torque_bandwidth_rad_s), ("flux", flux_bandwidth_rad_s)):
        if is_concrete(a) and float(a) * Ts >= 0.5:
            raise ParameterError(
                f"{name}_bandwidth_rad_s = {float(a):g} rad/s is too fast for Ts = {Ts:g} s (a Ts = "
                f"{float(a) * Ts:.2f} >= 0.5 with the one-period delay): choose a < {0.5 / Ts:g} rad/s "
                f"(a <= {0.25 / Ts:g} rad/s is not oscillatory)."
            )
    dtype = motor.R.dtype
    b_t = motor.torque_constant / motor.L_q
    k_t = jnp.asarray(1e3 * torque_rate_nm_per_ms, dtype) / b_t
    k_psi = jnp.asarray(flux_rate_wb_per_s, dtype)
    return {
        "torque_gain_v": k_t,
        "torque_boundary_nm": b_t * k_t / jnp.asarray(torque_bandwidth_rad_s, dtype),
        "flux_gain_v": k_psi,
        "flux_boundary_wb": k_psi / jnp.asarray(flux_bandwidth_rad_s, dtype),
    }
