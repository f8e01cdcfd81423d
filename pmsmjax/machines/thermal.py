"""A warm motor: temperature-dependent resistance and magnet flux, heated by a lumped thermal network.

**Machine physics** (winding temperature ``T``, K):

- ``R(T) = R (1 + alpha (T - T_ref))``; copper's ``alpha = 0.00393 /K`` at 20 degC (IEC 60028, the
  International Annealed Copper Standard: 3.93e-3 /K), so a winding 100 K above its reference has 1.39
  times the resistance;
- ``psi_f(T) = psi_f (1 + beta (T - T_ref))``; sintered NdFeB loses remanence at ``beta = -0.1`` to
  ``-0.12 %/K`` (``-0.001`` to ``-0.0012 /K``), SmCo about ``-0.03 %/K`` (magnet makers' data sheets, e.g.
  Arnold Magnetic Technologies, "Reversible temperature coefficients", and Gieras, *Permanent Magnet Motor
  Technology*, 3rd ed., 2010, ch. 2).

``R`` and ``psi_f`` are the motor's values at ``T_ref``. The network has **one node**: the winding, whose
temperature also sets the magnet flux (the magnet assumed at the winding's temperature, see Limits).

**Thermal network** (one node, ``C_th dT/dt = P_loss - (T - T_amb) / R_th``) heated by the copper loss of the
amplitude-invariant dq frame, ``P_cu = 1.5 R(T) |i_dq|^2`` (peak values: the three phases' ``sum R i_x^2``
for a balanced current; ``pmsmjax`` uses amplitude-invariant Clarke and Park transforms throughout).

**Integration, once per control period.** The thermal time constant ``R_th C_th`` is seconds to minutes, the
electrical ones are below a millisecond: integrating the temperature inside the RK4 sub-steps would add work
to every stage for a state that moves by micro-kelvins per period, and would make the electrical integrator's
step depend on a state it cannot resolve anyway. The network is linear for a held loss, so it is advanced
exactly (zero-order hold of the period's mean loss):

    ``T_{k+1} = T_k + (T_amb + P_k R_th - T_k) (1 - exp(-Ts / (R_th C_th)))``,

stable for any period. ``P_k`` is ``1.5 R(T_k)`` times the mean of ``|i_dq|^2`` at the period's start and end
(trapezoidal rule; the averaged bridge's current is smooth within a period). The plant sees ``R(T_k)`` and
``psi_f(T_k)`` for the whole period: a first-order lag of one period in the coupling, negligible against
``R_th C_th``.

**Float32.** A rise of micro-kelvins per period on a temperature of 300 K is below float32's resolution
(3e-5 K at 300 K): the state is the rise above ambient, summed with a compensation term (Kahan summation),
so the temperature rises correctly in the default float32 over millions of periods.

**Limits.** One node: the magnet follows the winding (in most radial-flux machines the rotor runs cooler
than the winding, by tens of kelvins at rated load: the flux drop is then overstated, the conservative side
for torque capability); no iron, friction or inverter loss heats the node; ``L_d``, ``L_q`` do not depend on
temperature. With a flux map the magnet's share of the flux is ``psi_d(0, 0)`` of the map and only it scales
(``psi_d(i) + (k_psi - 1) psi_d(0, 0)``): the saturation a warmer magnet relieves is not modelled.
"""

import equinox as eqx
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.machines.motor import as_float
from pmsmjax.spec.validation import check_finite, check_positive

__all__ = ["WindingThermal", "COPPER_ALPHA_PER_K"]

#: Resistance temperature coefficient of annealed copper at 20 degC, 1/K (IEC 60028).
COPPER_ALPHA_PER_K = 0.00393


class WindingThermal(eqx.Module):
    """The winding's lumped thermal network and the temperature coefficients of ``R`` and ``psi_f``
    (module docstring). Every field is an array leaf: tunable, vmappable (Monte Carlo draws the initial
    temperature and the ambient), differentiable.

    Args:
        r_th: Thermal resistance from the winding to ambient, K/W.
        c_th: Heat capacity of the winding node, J/K.
        ambient_k: Ambient (coolant) temperature, K.
        initial_k: Winding temperature at the start of a run, K.
        reference_k: Temperature at which the motor's ``R`` and ``psi_f`` hold, K.
        r_temp_coeff: ``alpha``, relative change of ``R`` per kelvin, 1/K (copper 0.00393).
        psi_f_temp_coeff: ``beta``, relative change of ``psi_f`` per kelvin, 1/K (NdFeB -0.001 to -0.0012).

    Raises:
        ParameterError: For a non-positive thermal resistance, capacity or temperature, or a non-finite
            coefficient.
    """

    r_th: Array = eqx.field(converter=as_float)
    c_th: Array = eqx.field(converter=as_float)
    ambient_k: Array = eqx.field(converter=as_float)
    initial_k: Array = eqx.field(converter=as_float)
    reference_k: Array = eqx.field(converter=as_float)
    r_temp_coeff: Array = eqx.field(converter=as_float)
    psi_f_temp_coeff: Array = eqx.field(converter=as_float)

    def __check_init__(self):
        check_positive("WindingThermal.r_th (thermal resistance)", self.r_th, "K/W")
        check_positive("WindingThermal.c_th (heat capacity)", self.c_th, "J/K")
        for name in ("ambient_k", "initial_k", "reference_k"):
            check_positive(f"WindingThermal.{name}", getattr(self, name), "K", "give temperatures in kelvin")
        check_finite("WindingThermal.r_temp_coeff", self.r_temp_coeff, "1/K")
        check_finite("WindingThermal.psi_f_temp_coeff", self.psi_f_temp_coeff, "1/K")

    @property
    def time_constant_s(self) -> Array:
        """``R_th C_th``, s."""
        return self.r_th * self.c_th

    def init(self, dtype) -> Array:
        """The network's state at the start of a run: ``(2,)`` the winding's rise above ambient (K) and
        its summation compensation (K, 0)."""
        rise = jnp.asarray(self.initial_k - self.ambient_k, dtype)
        return jnp.stack([rise, jnp.zeros_like(rise)])

    def temperature(self, state: Array) -> Array:
        """Winding temperature of a network state, K.

        Args:
            state: ``(..., 2)`` network state (`init`).
        """
        return self.ambient_k + state[..., 0]

    def factors(self, temperature_k) -> tuple[Array, Array]:
        """``(R(T) / R, psi_f(T) / psi_f)`` at the winding temperature ``temperature_k`` (K)."""
        dT = temperature_k - self.reference_k
        return 1.0 + self.r_temp_coeff * dT, 1.0 + self.psi_f_temp_coeff * dT

    def machine_at(self, machine, state: Array):
        """``machine`` at the network state's temperature: its ``R`` and ``psi_f`` scaled
        ([`AbstractMachine.at_temperature`][pmsmjax.machines.base.AbstractMachine.at_temperature]).

        Args:
            machine: The cold (reference-temperature) machine.
            state: ``(2,)`` network state.
        """
        k_r, k_psi = self.factors(self.temperature(state))
        return machine.at_temperature(k_r, k_psi)

    def copper_loss(self, resistance, i_dq_start, i_dq_end) -> Array:
        """Mean copper loss over a period, W: ``1.5 R |i_dq|^2`` (amplitude-invariant dq, peak currents)
        with ``|i_dq|^2`` averaged over the period's start and end (trapezoidal rule).

        Args:
            resistance: Phase resistance at the winding's temperature, ohm.
            i_dq_start: ``(2,)`` dq currents at the period start, A.
            i_dq_end: ``(2,)`` dq currents at the period end, A.
        """
        square = 0.5 * (jnp.sum(i_dq_start**2) + jnp.sum(i_dq_end**2))
        return 1.5 * resistance * square

    def step(self, state: Array, loss_w, Ts: float) -> Array:
        """Advance the network by one period under the held loss ``loss_w`` (W): the exact solution of
        the linear one-node network (module docstring), the increment added with Kahan compensation.

        Args:
            state: ``(2,)`` network state at the period start.
            loss_w: Mean loss over the period, W.
            Ts: Period, s.

        Returns:
            ``(2,)`` the network state at the period end.
        """
        rise, compensation = state[0], state[1]
        share = -jnp.expm1(-Ts / self.time_constant_s)
        increment = (loss_w * self.r_th - rise) * share
        y = increment - compensation
        total = rise + y
        return jnp.stack([total, (total - rise) - y])
