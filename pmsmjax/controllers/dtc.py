"""Switching-table direct torque control (the book, ch. 4; I. Takahashi and T. Noguchi, "A new
quick-response and high-efficiency control strategy of an induction motor", IEEE Trans. Ind. Appl.
IA-22(5), 820-827, 1986; for the PMSM: L. Zhong, M. F. Rahman, W. Y. Hu and K. W. Lim, "Analysis of
direct torque control in permanent magnet synchronous motor drives", IEEE Trans. Power Electron. 12(3),
528-536, 1997).

Per comparator sample (the drive's period ``Ts``, typically 20-50 us; no modulator), on the estimator's
stator flux ``psi_ab`` and torque ``T``
([`pmsmjax.estimators.StatorFluxObserver`][pmsmjax.estimators.flux_observer.StatorFluxObserver]):

1. the speed loop ([`AbstractSpeedController`][pmsmjax.controllers.base.AbstractSpeedController], the PI with
   active damping by default) every ``speed_divider`` samples. Its output is a q-axis current (A) in the FOC
   cascade; here it is scaled by the controller model's torque constant ``K_t = 1.5 p_n psi_f`` into the
   torque reference ``T* = K_t i_q*`` (N m), limited to the torque that keeps the current inside
   ``current_limit`` at the flux reference
   ([`torque_current_limit`][pmsmjax.controllers.dtc.torque_current_limit]: 16.1 N m on the book drive). With
   an ideal torque loop the mechanics see the same ``K_t i_q*`` as under FOC, so the same design rule gives
   the same speed loop. ``mode="torque"``: ``T* = K_t i_q*`` with the scenario's ``i_q*``.
2. the flux comparator, two-level with full band ``h_psi`` (Wb) on ``e_psi = psi* - |psi|``::

       phi = 1 (raise the flux)  if e_psi >  h_psi/2
       phi = 0 (lower it)        if e_psi < -h_psi/2,   else hold

3. the torque comparator on ``e_T = T* - T`` with full band ``h_T`` (N m):

   - three-level (default, ``torque_levels=3``)::

         tau = +1  if e_T >  h_T/2          (forward vector: torque up fast)
         tau = -1  if e_T < -h_T/2          (backward vector: torque down fast)
         tau =  0  if tau_prev = +1 and e_T <= 0, or tau_prev = -1 and e_T >= 0   (zero vector)
         else hold

     A zero vector stops the stator flux while the rotor flux moves on, so the load angle and the torque
     fall slowly in motoring; in steady motoring the torque cycles between ``T* - h_T/2`` (the zero
     vector's floor) and ``T*`` (where the forward vector ends), so its mean lies about ``h_T/4`` below
     ``T*`` (the speed loop's integral takes it up).
   - two-level (``torque_levels=2``): ``tau = +1`` above ``h_T/2``, ``-1`` below ``-h_T/2``, else hold:
     active vectors only (Zhong et al.), no zero vectors, faster and noisier.

4. the flux sector ``k`` (1..6) of ``psi_ab``: sector 1 from -30 to 30 deg, sector k centred on
   ``(k - 1) 60 deg``; and the switching table ([`SWITCHING_TABLE`][pmsmjax.controllers.dtc.SWITCHING_TABLE]),
   with the basic vectors ``V1`` (100) at 0 deg, ``V2`` (110) at 60 deg, ... ``V6`` (101) at 300 deg, ``V0``
   (000) and ``V7`` (111)::

        phi  tau   sector k = 1    2    3    4    5    6
         1   +1              V2   V3   V4   V5   V6   V1     V(k+1)
         1    0              V7   V0   V7   V0   V7   V0
         1   -1              V6   V1   V2   V3   V4   V5     V(k-1)
         0   +1              V3   V4   V5   V6   V1   V2     V(k+2)
         0    0              V0   V7   V0   V7   V0   V7
         0   -1              V5   V6   V1   V2   V3   V4     V(k-2)

   The zero vector is the one a single leg away from the active vector of the same row (V7 after
   V2, V4, V6; V0 after V1, V3, V5), so returning to it switches one leg.

The leg states go to the bridge directly (``command_kind = "switches"``) and are held until the next
sample: the averaged bridge is exact for them (the average of a held state is that state), and the
switching-resolved bridge, which puts each leg's pulse in the middle of the period, integrates a duty of 0
or 1 as a leg that does not switch (no edges inside the period). The switching frequency varies with the
operating point; it is at most ``1/(2 Ts)`` per leg.

Sampled, not analog: the comparators see the flux and torque only at the samples, so each can pass its
threshold by up to one sample's change before the table reverses it (on the book drive at 1000 r/min
under 10 N m, a 25 us sample moves the torque by up to 0.65 N m and the flux magnitude by up to 4.5 mWb);
tests/controllers/test_dtc.py checks that they stay within the bands widened by that, and measures where the
torque does not: just after ``V(k+2)`` in the first half of a sector, which lowers the flux magnitude faster
than
it advances the load angle.

Flux reference: ``flux_ref_wb`` (default the model's magnet flux ``psi_f``). A surface machine with
``|psi| = psi_f`` carries ``i_d = (sqrt(psi_f^2 - (L i_q)^2) - psi_f)/L``: -1.2 A at 10 N m on the book
motor, which ``i_dq_ref`` reports (the dq current of the model at ``|psi| = psi*``, ``T = T*``; DTC itself
has no current reference).

Gradients: the comparators, sector and table are piecewise constant, so the derivative of a run with
respect to the bands is zero almost everywhere, and no smooth surrogate is offered here; tune DTC with
[`SlidingModeDTC`][pmsmjax.controllers.smc_dtc.SlidingModeDTC], whose switching function has one, and set the
bands of this one by search
([`pmsmjax.jobs.equal_switching.match_switching_frequency`][pmsmjax.jobs.equal_switching.match_switching_frequency]).
"""

from typing import ClassVar, Literal

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from pmsmjax._types import Array
from pmsmjax.controllers.base import AbstractSpeedController
from pmsmjax.controllers.hysteresis import hysteresis_comparator
from pmsmjax.controllers.speed_cascade import AbstractDesignedSpeedCascade
from pmsmjax.frames.three_phase import abc_to_alpha_beta, park
from pmsmjax.machines.motor import PMSMParameters, as_float
from pmsmjax.signals import CommandKind, ControlOutput, Estimate, References, Sample
from pmsmjax.spec.validation import ParameterError, check_choice, check_positive

DTCMode = Literal["speed", "torque"]

__all__ = [
    "AbstractTorqueCascade",
    "DTCMode",
    "DTCState",
    "SWITCHING_TABLE",
    "SwitchingTableDTC",
    "VECTOR_SWITCHES",
    "flux_sector",
    "table_vector",
    "three_level_comparator",
    "torque_current_limit",
]

#: Leg states (a, b, c; 1 = upper switch on) of the vectors V0..V7.
VECTOR_SWITCHES = np.array(
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 1, 1], [0, 0, 1], [1, 0, 1], [1, 1, 1]], dtype=float
)


def _book_table() -> np.ndarray:
    """``(2, 3, 6)`` vector index by [phi (0, 1), tau + 1 (-1, 0, +1), sector - 1]."""
    table = np.zeros((2, 3, 6), dtype=np.int32)
    for s in range(6):
        k = s + 1
        active = lambda shift, k=k: (k - 1 + shift) % 6 + 1  # V(k + shift), 1..6
        table[1, 2, s] = active(1)
        table[1, 0, s] = active(-1)
        table[0, 2, s] = active(2)
        table[0, 0, s] = active(-2)
        # The zero vector one leg away from the tau = +1 vector of the same row.
        table[1, 1, s] = 7 if active(1) % 2 == 0 else 0
        table[0, 1, s] = 7 if active(2) % 2 == 0 else 0
    return table


#: The switching table: vector index (0..7) by [phi, tau + 1, sector - 1] (module docstring).
SWITCHING_TABLE = _book_table()


def flux_sector(psi_ab: Array) -> Array:
    """Sector 0..5 (sector 1..6 less one) of the flux ``psi_ab (2,)``: sector 1 spans -30..30 deg."""
    angle = jnp.arctan2(psi_ab[1], psi_ab[0])
    return jnp.floor((angle + jnp.pi / 6.0) / (jnp.pi / 3.0)).astype(jnp.int32) % 6


def table_vector(phi: Array, tau: Array, sector: Array) -> Array:
    """Vector index 0..7 of the table for flux state ``phi`` (0/1), torque state ``tau`` (-1/0/+1) and
    ``sector`` (0..5)."""
    table = jnp.asarray(SWITCHING_TABLE)
    return table[phi.astype(jnp.int32), tau.astype(jnp.int32) + 1, sector]


def three_level_comparator(error: Array, band: Array, previous: Array) -> Array:
    """Three-level hysteresis comparator (module docstring): ``tau`` in {-1, 0, +1} from the error
    ``e`` (units of ``band``), the full band ``h`` and the previous ``tau``."""
    half = 0.5 * band
    one = jnp.ones_like(previous)
    back_to_zero = ((previous > 0) & (error <= 0)) | ((previous < 0) & (error >= 0))
    held = jnp.where(back_to_zero, 0.0 * one, previous)
    return jnp.where(error > half, one, jnp.where(error < -half, -one, held))


def two_level_torque_comparator(error: Array, band: Array, previous: Array) -> Array:
    """``tau`` in {-1, +1}: +1 above ``band/2``, -1 below ``-band/2``, else held."""
    half = 0.5 * band
    return jnp.where(error > half, 1.0, jnp.where(error < -half, -1.0, previous))


class AbstractTorqueCascade(AbstractDesignedSpeedCascade):
    """What the two DTCs share: the speed-loop fields, a stator flux reference ``flux_ref_wb`` (Wb; ``None``
    takes ``model.psi_f``) and ``mode`` ``"speed"`` or ``"torque"`` (module docstring; the speed block's
    current becomes the torque reference through ``speed_torque_reference``).

    Args:
        model: The controller's motor model (torque constant, default speed design and flux reference).
        current_limit: Peak phase-current limit, A.
        speed: The speed block (its output a current, A), or ``None`` (the PI with active damping at
            ``speed_bandwidth`` rad/s).
        flux_ref_wb: Stator flux reference, Wb, or ``None``.
        mode: ``"speed"`` or ``"torque"`` (static).
        speed_divider: The speed loop runs every this many periods (static).
        speed_bandwidth: rad/s, only to design the default speed block.
    """

    modes: ClassVar[tuple[str, ...]] = ("speed", "torque")

    flux_ref_wb: Array

    def __init__(
        self, model: PMSMParameters, current_limit, speed, flux_ref_wb, mode, speed_divider, speed_bandwidth
    ):
        super().__init__(model, current_limit, speed, mode, speed_divider, speed_bandwidth)
        self.flux_ref_wb = model.psi_f if flux_ref_wb is None else as_float(flux_ref_wb)

    def __check_init__(self):
        check_positive(f"{type(self).__name__}.flux_ref_wb (stator flux reference)", self.flux_ref_wb, "Wb")


class DTCState(eqx.Module):
    speed: object  # the speed block's state
    torque_ref: Array  # N m, held between speed-loop updates
    counter: Array  # int32, samples since the last speed-loop update
    phi: Array  # flux comparator state, 0 or 1
    tau: Array  # torque comparator state, -1, 0 or +1


class SwitchingTableDTC(AbstractTorqueCascade):
    """Switching-table direct torque control under a speed loop (command: switch states; module docstring).

    **Arguments:**

    - `model`: the controller's motor model (torque constant, default speed design, flux reference,
      the implied current reference).
    - `torque_band_nm`: full torque band ``h_T``, N m.
    - `flux_band_wb`: full flux band ``h_psi``, Wb.
    - `current_limit`: peak phase-current limit, A: the torque reference is limited to what it allows at
      the flux reference ([`torque_current_limit`][pmsmjax.controllers.dtc.torque_current_limit]).
    - `speed`: the speed block (its output a current, A); ``None`` takes the PI with active damping at
      `speed_bandwidth` rad/s.
    - `flux_ref_wb`: stator flux reference ``psi*``, Wb; ``None`` takes ``model.psi_f``.
    - `torque_levels`: 3 (with zero vectors, default) or 2 (active vectors only) (static).
    - `mode`: ``"speed"`` (cascade) or ``"torque"`` (``T* = K_t i_q*`` of the scenario) (static).
    - `speed_divider`: the speed loop runs every this many samples (static).

    The drive's estimator must estimate the flux and torque
    ([`StatorFluxObserver`][pmsmjax.estimators.flux_observer.StatorFluxObserver]).
    """

    command_kind: ClassVar[CommandKind] = "switches"
    divider_unit: ClassVar[str] = "comparator samples"

    torque_band_nm: Array
    flux_band_wb: Array
    torque_levels: int = eqx.field(static=True)

    def __init__(
        self,
        model: PMSMParameters,
        torque_band_nm,
        flux_band_wb,
        current_limit,
        speed: AbstractSpeedController | None = None,
        *,
        flux_ref_wb=None,
        torque_levels: int = 3,
        mode: DTCMode = "speed",
        speed_divider: int = 1,
        speed_bandwidth=50.0,
    ):
        super().__init__(model, current_limit, speed, flux_ref_wb, mode, speed_divider, speed_bandwidth)
        self.torque_band_nm = as_float(torque_band_nm)
        self.flux_band_wb = as_float(flux_band_wb)
        self.torque_levels = torque_levels

    def __check_init__(self):
        check_positive("SwitchingTableDTC.torque_band_nm (full torque band)", self.torque_band_nm, "N m")
        check_positive("SwitchingTableDTC.flux_band_wb (full flux band)", self.flux_band_wb, "Wb")
        check_choice("torque_levels", self.torque_levels, (2, 3))

    def init(self, dtype=None) -> DTCState:
        dtype = self.state_dtype(dtype)
        zero = jnp.zeros((), dtype)
        # phi = 1, tau = 0 at rest: the zero vector until an error leaves a band.
        return DTCState(self.speed.init(dtype), zero, jnp.zeros((), jnp.int32), zero + 1.0, zero)

    def step(
        self, state: DTCState, sample: Sample, estimate: Estimate, refs: References, Ts, u_max, delayed
    ) -> tuple[DTCState, ControlOutput]:
        check_flux_estimate(type(self).__name__, sample, estimate)
        torque_ref, speed_state, counter = speed_torque_reference(self, state, estimate, refs, Ts)
        e_psi = self.flux_ref_wb - flux_magnitude(estimate.psi_ab)
        phi = hysteresis_comparator(e_psi, self.flux_band_wb, state.phi)
        e_t = torque_ref - estimate.torque
        if self.torque_levels == 3:
            tau = three_level_comparator(e_t, self.torque_band_nm, state.tau)
        else:
            tau = two_level_torque_comparator(e_t, self.torque_band_nm, state.tau)
        vector = table_vector(phi, tau, flux_sector(estimate.psi_ab))
        switches = jnp.asarray(VECTOR_SWITCHES, sample.u_dc.dtype)[vector]
        u_ab = abc_to_alpha_beta(sample.u_dc * (switches - jnp.mean(switches)))
        out = ControlOutput(
            switches, park(u_ab, estimate.theta_e), implied_current_reference(self, torque_ref)
        )
        return DTCState(speed_state, torque_ref, counter, phi, tau), out


# --- shared with the sliding-mode DTC ------------------------------------------------------------------


def check_flux_estimate(name: str, sample: Sample, estimate: Estimate) -> None:
    """Refuse (while tracing) a drive whose estimator gives no flux or torque, or a non-three-phase one."""
    if estimate.psi_ab is None or estimate.torque is None:
        raise ParameterError(
            f"{name} needs the stator flux and torque: give the Drive estimator="
            "pmsmjax.estimators.StatorFluxObserver(model, crossover_rad_s, position=...)."
        )
    if sample.i_phase.shape[-1] != 3:
        raise ParameterError(f"{name} drives three legs; the machine has {sample.i_phase.shape[-1]}.")


def flux_magnitude(psi_ab: Array) -> Array:
    """``|psi_ab|``, Wb, with the square root guarded at zero (finite gradient)."""
    sq = jnp.sum(psi_ab * psi_ab)
    safe = jnp.where(sq > 0, sq, 1.0)
    return jnp.where(sq > 0, jnp.sqrt(safe), 0.0)


def torque_current_limit(model: PMSMParameters, flux_ref_wb: Array, current_limit: Array) -> Array:
    """The largest torque-equivalent current ``T_max / K_t``, A, with ``|i| <= current_limit`` at
    ``|psi| = flux_ref_wb``.

    At the flux reference the current is not free: ``(L_d i_d + psi_f)^2 + (L_q i_q)^2 = psi*^2``. On the
    current circle ``i_d^2 + i_q^2 = I^2`` this gives ``a i_d^2 + b i_d + c = 0`` with
    ``a = L_d^2 - L_q^2``, ``b = 2 L_d psi_f``, ``c = psi_f^2 + L_q^2 I^2 - psi*^2``, solved as
    ``i_d = -2c / (b + sqrt(b^2 - 4ac))`` (the root near the surface machine's ``-c/b``), and then
    ``T_max = 1.5 p_n (psi_f + (L_d - L_q) i_d) i_q`` with ``i_q = sqrt(I^2 - i_d^2)``. For the book motor
    at ``psi* = psi_f`` and 15 A: ``i_d`` = -3.2 A, ``i_q`` = 14.65 A, ``T_max`` = 16.1 N m (``K_t I`` =
    16.4 N m would take 15.3 A). Zero where the flux reference cannot be held on the circle.
    """
    m = model
    a = m.L_d**2 - m.L_q**2
    b = 2.0 * m.L_d * m.psi_f
    c = m.psi_f**2 + (m.L_q * current_limit) ** 2 - flux_ref_wb**2
    disc = b * b - 4.0 * a * c
    root = jnp.sqrt(jnp.where(disc > 0, disc, 1.0))
    i_d = -2.0 * c / (b + root)
    iq_sq = current_limit**2 - i_d**2
    ok = (disc > 0) & (iq_sq > 0)
    i_q = jnp.sqrt(jnp.where(ok, iq_sq, 1.0))
    torque_max = 1.5 * m.pole_pairs * (m.psi_f + (m.L_d - m.L_q) * i_d) * i_q
    return jnp.where(ok, torque_max / m.torque_constant, 0.0)


def speed_torque_reference(
    controller: AbstractTorqueCascade, state, estimate: Estimate, refs: References, Ts
):
    """``(T* N m, speed state, counter)``: the speed block's current scaled by ``K_t``, every
    ``speed_divider`` samples (held in between), or ``K_t i_q*`` of the scenario in torque mode; limited
    to ``K_t`` times [`torque_current_limit`][pmsmjax.controllers.dtc.torque_current_limit], the current
    circle at the flux reference."""
    k_t = controller.model.torque_constant
    i_max = torque_current_limit(controller.model, controller.flux_ref_wb, controller.current_limit)
    if controller.mode == "speed":
        speed_state, torque_ref, counter = controller.held_speed_step(
            state, state.torque_ref, refs.speed_ref, estimate.omega_m, i_max, Ts, gain=k_t
        )
        return torque_ref, speed_state, counter
    return k_t * jnp.clip(refs.iq_ref, -i_max, i_max), state.speed, state.counter


def implied_current_reference(controller, torque_ref: Array) -> Array:
    """``(2,)`` A: the dq current of the controller's (surface) model with ``|psi| = psi*`` and
    ``T = T*``: ``i_q = T*/K_t``, ``i_d = (sqrt(psi*^2 - (L_q i_q)^2) - psi_f)/L_d`` (the root with
    the flux along d; ``-psi_f/L_d`` if ``L_q |i_q| > psi*``). What the trace records as ``i_dq_ref``."""
    m = controller.model
    iq = torque_ref / m.torque_constant
    rest = controller.flux_ref_wb**2 - (m.L_q * iq) ** 2
    root = jnp.sqrt(jnp.where(rest > 0, rest, 1.0)) * (rest > 0)
    return jnp.stack([(root - m.psi_f) / m.L_d, iq])
