"""Ripple: harmonics of the magnet flux linked by the stator, and cogging torque, of a three-phase PMSM.

**Magnet flux harmonics** (Gieras, *Permanent Magnet Motor Technology*, 3rd ed., 2010, ch. 5: the EMF of a
real winding carries the space harmonics of the magnets' field). Phase ``x`` (a, b, c; axis
``s_x = 0, 2pi/3, 4pi/3``) links, besides the fundamental ``psi_f cos(theta_e - s_x)``,

    ``psi_h,x = sum_k A_k cos(k (theta_e - s_x) + phi_k)``    (Wb; ``theta_e`` the d axis from phase a)

with ``k`` whole orders per electrical revolution. Amplitude-invariant Clarke gives, with the sequence
``sigma_k = +1`` for ``k = 1 mod 3`` (positive: 7, 13, ...) and ``-1`` for ``k = 2 mod 3`` (negative: 5,
11, ...),

    ``psi_h,ab = sum_k A_k [cos(k th + phi_k), sigma_k sin(k th + phi_k)]``,

and Park by ``theta_e`` puts each order at ``k - sigma_k`` in the rotor frame (the 5th and the 7th both at the
6th)

    ``psi_h,dq = sum_k A_k [cos(m_k), sigma_k sin(m_k)]``,  ``m_k = (k - sigma_k) th + phi_k``.

Triplen orders (``k = 0 mod 3``) are the same in all three phases: a zero-sequence EMF that a star winding
without neutral connection shows between phase and neutral but not between lines; it drives no current
and makes no torque, so they are refused ([`check_flux_orders`][pmsmjax.machines.harmonics.check_flux_orders])
rather than simulated (the abc model applies no neutral-point voltage and would let them drive a
zero-sequence current). The fundamental (``k = 1``) is ``psi_f``.

The back-EMF is ``d psi_h / dt = w_e d psi_h / d th``. In the rotor frame the voltage equations gain
``w_e eps_dq`` with ``eps_dq = d psi_h,dq / d th + J psi_h,dq = sum_k A_k k [-sin m_k, sigma_k cos m_k]`` (the
stator-frame ``d psi_h,ab / d th`` seen from the rotor), and the co-energy
``W' = 1.5 (1/2 i^T L i + i^T psi_pm(th))`` gives the torque ``T_e = p dW'/dth_e``, which adds
``1.5 p i_dq . eps_dq`` (N m) to the sinusoidal machine's: the harmonic's EMF times the current, over the
speed. The harmonics do not depend on the current (no saturation of the harmonic field): ``L`` and the
stored magnetic energy are the machine's.

**Cogging torque** (Zhu and Howe, "Influence of design parameters on cogging torque in permanent magnet
machines", IEEE Trans. Energy Conversion 15(4), pp. 407-412, 2000): the magnets' attraction to the
stator teeth, a torque of zero mean at zero current, periodic in the slot pitch:

    ``T_cog = sum_j C_j sin(n_j theta_e + phi_j)``   (N m on the shaft, ``n_j`` per electrical revolution).

It is conservative: ``T_cog = -dW_cog/dtheta_m`` with ``theta_e = p theta_m``, so the cogging co-energy is
``W_cog = (1/p) sum_j (C_j / n_j) cos(n_j theta_e + phi_j)`` (J), which the power balance counts with the
magnetic energy. A motor of ``Q`` slots and ``2p`` poles cogs ``lcm(Q, 2p)`` times per mechanical revolution,
``lcm(Q, 2p) / p`` per electrical one (12 slots, 8 poles: 6 and its multiples).

The machines ([`pmsmjax.machines.pmsm3`][pmsmjax.machines.pmsm3],
[`pmsmjax.machines.pmsm_flux_map`][pmsmjax.machines.pmsm_flux_map]) take a
[`MagnetHarmonics`][pmsmjax.machines.harmonics.MagnetHarmonics] as their optional ``harmonics`` field and add
the cogging torque to their ``torque`` (the torque the machine puts on the rotor); ``None`` (the default)
leaves their programs as they were.

**Limits.** The amplitudes hold at the motor's reference temperature (a warm magnet scales ``psi_f``, not
them); the harmonics do not saturate with the current; cogging and the harmonics repeat per electrical
revolution (a rotor's eccentricity or a magnet's misplacement, which repeat per mechanical revolution, are
not modelled); the RK4 sub-step rule judges the fundamental's ``w_e`` only, so the highest order ``n`` needs
``n w_e Ts / n_substeps`` well below 1 (at 3000 r/min, 4 pole pairs, 10 kHz, 10 sub-steps and ``n = 12``:
0.15 rad).
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from pmsmjax._types import Array
from pmsmjax.machines.integrate import rotate_back
from pmsmjax.machines.motor import as_float
from pmsmjax.spec.validation import ParameterError, check_finite, check_nonnegative

__all__ = [
    "MagnetHarmonics",
    "check_flux_orders",
    "check_cogging_orders",
    "sequence",
    "phasors",
    "cos_sin",
    "stator_axis",
    "PHASE_SHIFTS",
]

#: Phase axes a, b, c, rad (NumPy float64; converted where used so the precision of that moment applies).
PHASE_SHIFTS = np.array([0.0, 2.0 * np.pi / 3.0, 4.0 * np.pi / 3.0])


def _orders(orders, name: str) -> tuple[int, ...]:
    out = []
    for k in orders:
        if isinstance(k, bool) or not float(k).is_integer() or k < 1:
            raise ParameterError(
                f"{name} order {k!r} must be a whole number >= 1 (orders per electrical revolution)."
            )
        out.append(int(k))
    return tuple(out)


def check_flux_orders(orders, name: str = "MagnetHarmonics.flux") -> tuple[int, ...]:
    """The flux harmonics' orders as ints, refused in one line unless each is a whole number >= 2 that is
    not a multiple of 3 (module docstring: triplen orders drive no current in a star winding)."""
    orders = _orders(orders, name)
    for k in orders:
        if k == 1:
            raise ParameterError(
                f"{name} order 1 is the fundamental, which [motor] psi_f gives: drop it from the harmonics."
            )
        if k % 3 == 0:
            raise ParameterError(
                f"{name} order {k} is triplen: zero-sequence, it drives no current and makes no torque in a "
                "star winding without neutral (phase EMF only, not line): drop it."
            )
    return orders


def check_cogging_orders(orders, name: str = "MagnetHarmonics.cogging") -> tuple[int, ...]:
    """The cogging torque's orders as ints, each a whole number >= 1 (refused in one line otherwise)."""
    return _orders(orders, name)


def cos_sin(x) -> tuple[Array, Array]:
    """``(cos x, sin x)`` without transcendental functions: ``x`` reduced to one turn, the Taylor series of
    [`rotate_back`][pmsmjax.machines.integrate.rotate_back] at an eighth of it (``|x/8| <= pi/8``, where the
    series is exact to the float type's rounding), then three double-angle steps (rounding below 1e-15 in
    float64, 1e-6 in float32). XLA:CPU evaluates ``jnp.cos`` and ``jnp.sin`` element by element; these
    products fuse into a batched run's loop, which made a batch with ripple several times cheaper.

    Args:
        x: Angle, rad (any magnitude a run reaches; reduced by whole turns).
    """
    turns = jnp.round(x * (0.5 / np.pi))
    y = (x - turns * (2.0 * np.pi)) * 0.125
    c, minus_s = rotate_back(jnp.stack([jnp.ones_like(y), jnp.zeros_like(y)]), y)
    s = -minus_s
    for _ in range(3):
        c, s = c * c - s * s, 2.0 * c * s
    return c, s


def stator_axis(theta_e) -> Array:
    """``(2,)`` ``[cos theta_e, -sin theta_e]``: the stator's alpha axis seen from the rotor frame at the
    electrical angle ``theta_e`` (rad), by [`cos_sin`][pmsmjax.machines.harmonics.cos_sin]. The rotor-frame
    integrators carry it through a period's RK4 stages, rotated back by each stage's angle increment as
    the held voltage is ([`pmsmjax.machines.integrate.advance`][pmsmjax.machines.integrate.advance]), so the
    harmonics read ``(cos th, sin th)`` from it without evaluating it at every stage."""
    c, s = cos_sin(theta_e)
    return jnp.stack([c, -s])


def _powers(unit, multiples) -> dict[int, tuple[Array, Array]]:
    """``{n: (cos n th, sin n th)}`` for each static whole ``n >= 1`` in ``multiples``, from ``unit = (cos th,
    sin th)``: the powers of ``exp(j th)`` by repeated squaring, shared between equal or halved multiples
    (6 and 12 cost four complex products together)."""
    c1, s1 = unit
    cache = {1: (c1, s1)}

    def power(n):
        if n not in cache:
            c, s = power(n // 2)
            c, s = c * c - s * s, 2.0 * c * s
            if n % 2:
                c, s = c * c1 - s * s1, s * c1 + c * s1
            cache[n] = (c, s)
        return cache[n]

    return {int(n): power(int(n)) for n in multiples}


def phasors(theta, multiples: tuple[int, ...], phase) -> list[tuple[Array, Array]]:
    """``[(cos(n th + phi_n), sin(n th + phi_n)), ...]``, one pair per static whole multiple ``n >= 1`` of
    ``theta`` (rad), with the phases ``phase`` (``(len(multiples),)`` rad).

    One [`cos_sin`][pmsmjax.machines.harmonics.cos_sin] of ``theta``, then the powers of ``exp(j th)``
    by repeated squaring (shared between equal or halved multiples): in an RK4 stage transcendental
    functions cost more than the rest of a rotor-frame model's arithmetic (docs/performance.md,
    "Engine"). Scalars throughout (no stacking or summing over an axis), so that a batched run fuses
    them into the stage's loop. Rounding grows with ``log2 n`` products: below 1e-6 relative in float32
    for ``n <= 64``.
    """
    powers = _powers(cos_sin(theta), multiples)
    out = []
    for j, n in enumerate(multiples):
        cn, sn = powers[int(n)]
        cp, sp = jnp.cos(phase[..., j]), jnp.sin(phase[..., j])
        out.append((cn * cp - sn * sp, sn * cp + cn * sp))
    return out


def sequence(orders) -> np.ndarray:
    """``sigma_k``: +1 for a positive-sequence order (``k = 1 mod 3``), -1 for a negative one."""
    return np.where(np.asarray(orders) % 3 == 1, 1.0, -1.0)


class MagnetHarmonics(eqx.Module):
    """Flux harmonics and cogging torque (module docstring). Amplitudes and phases are array leaves:
    tunable, vmappable (Monte Carlo can draw them), differentiable; the orders are static whole numbers
    (each fixes its harmonic's sequence, as ``pole_pairs`` is static in the motor's parameters).

    Args:
        flux_orders: ``(K,)`` orders ``k`` of the stator flux harmonics, per electrical revolution (not 1,
            not triplen); ``()`` for none.
        flux_amplitude: ``(K,)`` amplitudes ``A_k``, Wb (peak per phase).
        flux_phase: ``(K,)`` phases ``phi_k``, rad.
        cogging_orders: ``(M,)`` orders ``n_j`` of the cogging torque, per electrical revolution; ``()`` for
            none.
        cogging_amplitude: ``(M,)`` amplitudes ``C_j``, N m.
        cogging_phase: ``(M,)`` phases ``phi_j``, rad.

    Raises:
        ParameterError: For orders that are not whole numbers (flux: 1 or triplen), shapes that do not
            match their orders, negative amplitudes or non-finite phases.
    """

    flux_amplitude: Array | None
    flux_phase: Array | None
    cogging_amplitude: Array | None
    cogging_phase: Array | None
    flux_orders: tuple[int, ...] = eqx.field(static=True)
    cogging_orders: tuple[int, ...] = eqx.field(static=True)

    def __init__(
        self, flux_orders=(), flux_amplitude=(), flux_phase=(), cogging_orders=(), cogging_amplitude=(),
        cogging_phase=(),
    ):  # fmt: skip
        self.flux_orders = check_flux_orders(flux_orders)
        self.cogging_orders = check_cogging_orders(cogging_orders)
        parts = (
            ("flux", self.flux_orders, flux_amplitude, flux_phase, "Wb"),
            ("cogging", self.cogging_orders, cogging_amplitude, cogging_phase, "N m"),
        )
        for name, orders, amplitude, phase, unit in parts:
            if not orders:
                setattr(self, f"{name}_amplitude", None)
                setattr(self, f"{name}_phase", None)
                continue
            amplitude, phase = as_float(amplitude), as_float(phase)
            if amplitude.shape[-1:] != (len(orders),) or phase.shape[-1:] != (len(orders),):
                raise ParameterError(
                    f"MagnetHarmonics.{name}: {len(orders)} orders need as many amplitudes and phases, got "
                    f"shapes {amplitude.shape} and {phase.shape}."
                )
            check_nonnegative(
                f"MagnetHarmonics.{name}_amplitude", amplitude, unit, "give a phase shift of pi"
            )
            check_finite(f"MagnetHarmonics.{name}_phase", phase, "rad")
            setattr(self, f"{name}_amplitude", amplitude)
            setattr(self, f"{name}_phase", phase)

    @classmethod
    def from_rows(cls, flux=(), cogging=()) -> "MagnetHarmonics":
        """From the drive file's rows ``[[order, amplitude, phase], ...]`` (``[harmonics]`` flux, Wb, and
        cogging, N m; phases in rad)."""
        f, c = np.asarray(flux, float).reshape(-1, 3), np.asarray(cogging, float).reshape(-1, 3)
        return cls(tuple(f[:, 0]), f[:, 1], f[:, 2], tuple(c[:, 0]), c[:, 1], c[:, 2])

    @property
    def has_flux(self) -> bool:
        """Whether there are flux harmonics (static)."""
        return bool(self.flux_orders)

    @property
    def has_cogging(self) -> bool:
        """Whether there is a cogging torque (static)."""
        return bool(self.cogging_orders)

    # --- flux, in each frame from its own formula ---------------------------------------------------
    def flux_abc(self, theta_e) -> Array:
        """``(3,)`` harmonic flux linked by phases a, b, c at the electrical angle ``theta_e`` (rad), Wb:
        ``sum_k A_k cos(k (th - s_x) + phi_k)``."""
        k = np.asarray(self.flux_orders, float)[:, None]
        angle = k * (theta_e - PHASE_SHIFTS[None, :]) + self.flux_phase[:, None]
        return jnp.sum(self.flux_amplitude[:, None] * jnp.cos(angle), axis=0)

    def flux_alpha_beta(self, theta_e) -> tuple[Array, Array]:
        """``(psi_h,ab (2,) Wb, d psi_h,ab / d theta_e (2,) Wb/rad)`` at ``theta_e`` (rad)."""
        psi_a = psi_b = dpsi_a = dpsi_b = 0.0
        pairs = phasors(theta_e, self.flux_orders, self.flux_phase)
        rows = zip(self.flux_orders, sequence(self.flux_orders), pairs, strict=True)
        for j, (k, sigma, (cos, sin)) in enumerate(rows):
            c, s = self.flux_amplitude[..., j] * cos, self.flux_amplitude[..., j] * sin
            psi_a, psi_b = psi_a + c, psi_b + sigma * s
            dpsi_a, dpsi_b = dpsi_a - k * s, dpsi_b + k * sigma * c
        return jnp.stack([psi_a, psi_b]), jnp.stack([dpsi_a, dpsi_b])

    def emf_dq(self, theta_e, unit=None) -> Array:
        """``eps_dq (2,)``, Wb/rad: the rotor-frame harmonic EMF per electrical rad/s,
        ``d psi_h,dq / d th + J psi_h,dq = sum_k A_k k [-sin m_k, sigma_k cos m_k]`` (module docstring);
        the voltage equations add ``w_e eps_dq`` and the torque ``1.5 p i_dq . eps_dq``.

        Args:
            theta_e: Electrical angle, rad.
            unit: ``(cos theta_e, sin theta_e)`` where the caller carries them
                ([`rotor_terms`][pmsmjax.machines.harmonics.MagnetHarmonics.rotor_terms]); ``None``: from
                ``theta_e``.
        """
        e_d, e_q, _ = self.rotor_terms(theta_e, unit)
        return jnp.stack([e_d, e_q])

    def rotor_terms(self, theta_e, unit=None) -> tuple[Array, Array, Array]:
        """``(e_d, e_q, T_cog)`` at ``theta_e`` (rad): the rotor-frame harmonic EMF per electrical rad/s
        ``eps_dq`` (Wb/rad; 0 without flux harmonics) and the cogging torque (N m; 0 without cogging).

        Every term is a whole multiple ``M`` of ``theta_e`` (``k - sigma_k`` for a flux order, ``n_j`` for
        cogging), so ``sin(M th + phi) = sin(M th) cos phi + cos(M th) sin phi`` puts each in the form
        ``a_M cos(M th) + b_M sin(M th)``: the coefficients depend on the amplitudes and phases only (the
        loop's invariants, which XLA computes once before it), and orders at the same multiple (the 5th
        and the 7th at the 6th) share one ``(cos M th, sin M th)``. Those come from one ``(cos th, sin
        th)`` by repeated squaring of ``exp(j th)`` (four complex products for the
        multiples 6 and 12): a short chain of scalar products, which matters because XLA:CPU copies a
        value's whole chain into every fused kernel that reads it (docs/performance.md, "Ripple").

        Args:
            theta_e: Electrical angle, rad.
            unit: ``(cos theta_e, sin theta_e)`` where the caller carries them (the rotor-frame
                integrators rotate them by each RK4 stage's angle increment, as the held voltage:
                [`pmsmjax.machines.integrate.advance`][pmsmjax.machines.integrate.advance]); ``None``:
                [`cos_sin`][pmsmjax.machines.harmonics.cos_sin] of ``theta_e``.
        """
        rows = {}  # (term: 0 e_d, 1 e_q, 2 T_cog; multiple M) -> [a_M, b_M]

        def add(term, multiple, a, b):
            key = (term, int(multiple))
            rows[key] = [a, b] if key not in rows else [rows[key][0] + a, rows[key][1] + b]

        for j, (k, sigma) in enumerate(zip(self.flux_orders, sequence(self.flux_orders), strict=True)):
            ka = k * self.flux_amplitude[..., j]
            cp, sp = jnp.cos(self.flux_phase[..., j]), jnp.sin(self.flux_phase[..., j])
            add(0, k - sigma, -ka * sp, -ka * cp)  # -k A sin(M th + phi), M = k - sigma
            add(1, k - sigma, sigma * ka * cp, -sigma * ka * sp)  # sigma k A cos(M th + phi)
        for j, n in enumerate(self.cogging_orders):
            amplitude, phase = self.cogging_amplitude[..., j], self.cogging_phase[..., j]
            add(2, n, amplitude * jnp.sin(phase), amplitude * jnp.cos(phase))  # C sin(n th + phi)
        multiples = tuple(sorted({multiple for _, multiple in rows}))
        powers = _powers(cos_sin(theta_e) if unit is None else unit, multiples)
        terms = [None, None, None]
        for (term, multiple), (a, b) in rows.items():
            c, s = powers[multiple]
            terms[term] = a * c + b * s if terms[term] is None else terms[term] + a * c + b * s
        zero = jnp.zeros_like(theta_e)
        return tuple(zero if t is None else t for t in terms)

    def flux_dq(self, theta_e) -> Array:
        """``psi_h,dq (2,)``, Wb, at ``theta_e`` (rad): the harmonics seen from the rotor."""
        k = np.asarray(self.flux_orders, float)
        sigma = sequence(self.flux_orders)
        m = (k - sigma) * theta_e + self.flux_phase
        a = self.flux_amplitude
        return jnp.stack([jnp.sum(a * jnp.cos(m)), jnp.sum(sigma * a * jnp.sin(m))])

    # --- cogging -------------------------------------------------------------------------------------
    def cogging_torque(self, theta_e, unit=None) -> Array:
        """Cogging torque at the electrical angle ``theta_e`` (rad), N m (0 without cogging); ``unit`` as in
        [`rotor_terms`][pmsmjax.machines.harmonics.MagnetHarmonics.rotor_terms]."""
        if not self.has_cogging:
            return jnp.zeros_like(theta_e)
        return self.rotor_terms(theta_e, unit)[2]

    def cogging_energy(self, theta_e, pole_pairs: int) -> Array:
        """Cogging co-energy ``W_cog`` at ``theta_e`` (rad), J: ``T_cog = -dW_cog/dtheta_m``."""
        if not self.has_cogging:
            return jnp.zeros_like(theta_e)
        n = np.asarray(self.cogging_orders, float)
        return jnp.sum(self.cogging_amplitude / n * jnp.cos(n * theta_e + self.cogging_phase)) / pole_pairs

    def dq_torque(self, i_dq, theta_e, pole_pairs: int, unit=None) -> Array:
        """What the harmonics add to a rotor-frame model's torque, N m: ``1.5 p i_dq . eps_dq`` plus the
        cogging torque.

        Args:
            i_dq: ``(2,)`` dq currents, A.
            theta_e: Electrical angle, rad.
            pole_pairs: Pole pairs.
            unit: ``(cos theta_e, sin theta_e)`` or ``None``, as in
                [`rotor_terms`][pmsmjax.machines.harmonics.MagnetHarmonics.rotor_terms].
        """
        e_d, e_q, torque = self.rotor_terms(theta_e, unit)
        if self.has_flux:
            torque = torque + 1.5 * pole_pairs * (i_dq[0] * e_d + i_dq[1] * e_q)
        return torque
