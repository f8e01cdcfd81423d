"""Space-vector PWM for any multi-phase layout with two VSD planes: near-four-vector and large-vector SVPWM
(the book, ch. 8: the six-phase four-vector and two-vector methods; chapter 10: five phases).

In the sector ``k`` of the alpha-beta reference (between the large vectors L_k and L_k+1,
[`multiphase_vectors`][pmsmjax.inverters.multiphase_vectors])
[`NearFourVectorSVPWM`][pmsmjax.inverters.multiphase_svpwm.NearFourVectorSVPWM] applies L_k, L_k+1 and the two
collinear vectors of the next group (six phases: the medium-large vectors ML_k, ML_k+1; five phases: the
medium vectors M_k, M_k+1) for the dwell fractions that solve

    [L_k  L_k+1  S_k  S_k+1] t = [u_alpha, u_beta, u_x, u_y] / U_dc

(all four planes' components of each state), so the second plane's (z1-z2's, x-y's) period average is the
commanded one, zero for a ``(2,)`` reference. Six phases: the four-vector SVPWM of Zhao & Lipo, IEEE TIA
31(5), 1995 (preset name ``four-vector``); five phases: the "near-four-vector" method of Iqbal & Levi,
"Space vector PWM techniques for sinusoidal output voltage generation with a five-phase voltage source
inverter", Electric Power Components and Systems 34(2), 2006. The rest of the period is shared equally
by the zero states, leg ``x``'s duty ``d_x = sum_i t_i b_{i,x} + t_0/2``; the bridge realises it by
centre-aligned carrier comparison, so the period average of the applied voltage is exactly
``sum_i t_i V_i`` (volt-second balance).

**Linear range** (second-plane reference 0): the dwell times sum to one at the sector bisectors, at
``|u| = U_dc / (2 cos(pi/10)) = 0.5257 U_dc`` for five phases
([`NearFourVectorSVPWM.linear_limit`][pmsmjax.inverters.multiphase_svpwm.NearFourVectorSVPWM.linear_limit]
computes it from the tables: ``1 / sum(t)`` for a unit reference along a bisector). That is the same limit as
carrier PWM with min-max zero-sequence injection
([`multiphase_carrier`][pmsmjax.inverters.multiphase_carrier]), and on one star (five phases) the two give the
same duties inside it (the zero states split equally is min-max injection): a check of each against the other.
Six phases: each three-phase star then carries the reference itself, so its hexagon limits it,
``U_dc/sqrt(3)``, as each set's own SVPWM; the carrier's two zero sequences (one per star) give other duties
than the dwell times' common one, with the same period average.

[`LargeVectorSVPWM`][pmsmjax.inverters.multiphase_svpwm.LargeVectorSVPWM] is the contrast (six phases: the
two-vector method, preset name ``two-vector``): only L_k, L_k+1, ``[L_k L_k+1]_ab t = u_ab / U_dc``, the
second plane's average left as it falls (per unit of dwell time: six phases ``0.1725 U_dc``, driving 5th and
7th harmonic currents through the small z1-z2 leakage impedance; five phases ``0.2472 U_dc``, third and
seventh); linear to the inscribed circle of the L polygon, ``|L| cos(pi/K)`` (six phases
``(2/3) cos^2(15 deg) = 0.6220 U_dc``; five phases ``(4/5) cos 36 deg cos 18 deg = 0.6155 U_dc``).

Sequence. The four vectors of a sector do not form a chain of nested states (no centre-aligned order
switches them one leg at a time), so the carrier realisation passes through other intermediate states
inside the period; its period average is the method's exactly. This is the usual DSP implementation
(leg compare values from the dwell times).

Over-modulation: dwell times beyond the period are scaled to it (direction kept, second-plane average
still as commanded up to that scale); negative dwell times (an unreachable second-plane command) are set
to zero. Reference: ``(2,)`` [alpha, beta] or ``(4,)`` [alpha, beta, x, y] (six phases: z1, z2), V.
"""

import abc
import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from pmsmjax._types import Array
from pmsmjax.frames.multiphase import FIVE_PHASE, PhaseLayout
from pmsmjax.inverters.base import AbstractModulator
from pmsmjax.inverters.multiphase_vectors import space_vectors
from pmsmjax.spec.validation import ParameterError

__all__ = [
    "AbstractSectorSVPWM",
    "LargeVectorSVPWM",
    "NearFourVectorSVPWM",
    "four_vector_tables",
    "padded_reference",
]


def padded_reference(u_ref: Array, n_active: int = 4) -> Array:
    """VSD reference from an alpha-beta one (other planes 0) or a full one.

    Args:
        u_ref: ``(2,)`` or ``(n_active,)`` reference, V.
        n_active: Length of the full reference.

    Returns:
        ``(n_active,)`` reference, V.
    """
    shape = jnp.shape(u_ref)
    if shape == (2,):
        return jnp.concatenate([u_ref, jnp.zeros(n_active - 2, jnp.result_type(u_ref))])
    if shape == (n_active,):
        return u_ref
    raise ParameterError(
        f"this modulator takes a (2,) [alpha, beta] or ({n_active},) VSD reference, got {shape}."
    )


@functools.lru_cache(maxsize=8)
def four_vector_tables(layout: PhaseLayout) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-sector tables of the near-four-vector SVPWM.

    Args:
        layout: The winding layout.

    Returns:
        ``inv (K, 4, 4)`` the inverse of ``[L_k L_k+1 S_k S_k+1]`` (columns the states' VSD vectors per
        unit of ``U_dc``), ``states (K, 4, n)`` their leg states, ``bisectors (K, 2)``.
    """
    if layout.n_active != 4:
        raise ParameterError(
            f"near-four-vector SVPWM needs two VSD planes; the layout {layout.name!r} has {layout.n_planes}."
        )
    sv = space_vectors(layout)
    K = len(sv.large)
    nxt = lambda idx: np.roll(idx, -1)
    columns = [sv.large, nxt(sv.large), sv.second, nxt(sv.second)]
    inv = np.empty((K, 4, 4))
    states = np.empty((K, 4, layout.n))
    for k in range(K):
        idx = [c[k] for c in columns]
        inv[k] = np.linalg.inv(sv.vectors[idx].T)
        states[k] = sv.states[idx]
    for a in (inv, states):
        a.setflags(write=False)
    return inv, states, sv.bisectors


@functools.lru_cache(maxsize=8)
def large_vector_tables(layout: PhaseLayout) -> tuple[np.ndarray, np.ndarray]:
    """Per-sector tables of the large-vector SVPWM.

    Args:
        layout: The winding layout.

    Returns:
        ``inv (K, 2, 2)`` of ``[L_k L_k+1]`` on alpha-beta, ``states (K, 2, n)``.
    """
    sv = space_vectors(layout)
    K = len(sv.large)
    inv = np.empty((K, 2, 2))
    states = np.empty((K, 2, layout.n))
    for k in range(K):
        idx = [sv.large[k], sv.large[(k + 1) % K]]
        inv[k] = np.linalg.inv(sv.vectors[idx, :2].T)
        states[k] = sv.states[idx]
    for a in (inv, states):
        a.setflags(write=False)
    return inv, states


def _select(table: np.ndarray, k: Array, dtype) -> Array:
    """``table[k]`` as a one-hot product (its reverse-mode derivative stays a product, not a scatter)."""
    one_hot = jax.nn.one_hot(k, table.shape[0], dtype=dtype)
    return jnp.tensordot(one_hot, jnp.asarray(table, dtype), axes=1)


def _duties(t: Array, states: Array) -> Array:
    """Leg duties from dwell fractions ``t (m,)`` of states ``(m, n)`` (negative times set to 0, scaled to
    the period if they exceed it), the zero states sharing the rest equally."""
    t = jnp.maximum(t, 0.0)
    total = jnp.sum(t)
    over = total > 1.0
    t = t * jnp.where(over, 1.0 / jnp.where(over, total, 1.0), 1.0)  # double-where: finite gradient
    return t @ states + 0.5 * (1.0 - jnp.sum(t))


class AbstractSectorSVPWM(AbstractModulator):
    """SVPWM of an n-phase winding from per-sector tables: the sector is the alpha-beta bisector the reference
    projects most on, the dwell fractions the sector's inverse table times the reference, and the duties those
    fractions spread over the sector's switching states (centre-aligned). A subclass holds the winding
    ``layout`` (static) and gives the ``tables``.
    """

    layout: eqx.AbstractVar[PhaseLayout]

    @property
    def n_phases(self) -> int:  # type: ignore[override]
        """Number of legs, one per phase of ``layout``."""
        return self.layout.n

    @abc.abstractmethod
    def tables(self) -> tuple[np.ndarray, np.ndarray]:
        """``(inv, states)``: per sector, the matrix from the reference (V over ``U_dc``) to the dwell
        fractions, and the switching states of the vectors those fractions weight."""

    def sector(self, u_ab: Array) -> Array:
        """Sector index (int) of an alpha-beta vector: the bisector it projects most on.

        Args:
            u_ab: ``(2,)`` vector.
        """
        _, _, bisectors = four_vector_tables(self.layout)
        return jnp.argmax(jnp.asarray(bisectors, u_ab.dtype) @ u_ab)

    def dwell_times(self, u_ref: Array, u_dc: Array) -> tuple[Array, Array]:
        """Sector and dwell fractions of the sector's vectors before any scaling (near-four-vector: L_k,
        L_k+1, S_k, S_k+1 from the full reference; large-vector: L_k, L_k+1 from its alpha-beta part).

        Args:
            u_ref: ``(2,)`` or full VSD reference, V.
            u_dc: DC-link voltage, V.

        Returns:
            ``(k, t (m,))``, ``m`` the number of vectors (4 or 2).
        """
        u = padded_reference(u_ref, self.layout.n_active)
        inv, _ = self.tables()
        k = self.sector(u[:2])
        return k, _select(inv, k, u.dtype) @ (u[: inv.shape[-1]] / u_dc)

    def duties(self, u_ref, u_dc):
        k, t = self.dwell_times(u_ref, u_dc)
        _, states = self.tables()
        return _duties(t, _select(states, k, t.dtype))


class NearFourVectorSVPWM(AbstractSectorSVPWM):
    """Near-four-vector SVPWM (module docstring): two large and two next vectors per sector, the second
    plane's average nulled (or as commanded).

    Args:
        layout: The winding (static), default five phases.
        name: The modulator's name in tables and figures (static).
    """

    layout: PhaseLayout = eqx.field(static=True, default=FIVE_PHASE)
    name: str = eqx.field(static=True, default="near-four-vector")

    def __check_init__(self):
        four_vector_tables(self.layout)  # raises for a layout without two planes

    def tables(self) -> tuple[np.ndarray, np.ndarray]:
        inv, states, _ = four_vector_tables(self.layout)
        return inv, states

    def linear_limit(self, u_dc):
        """``U_dc / sum(t)`` for a unit reference along a bisector (second plane 0), V peak (five phases:
        ``U_dc / (2 cos 18 deg)``); stars of three phases: ``U_dc/sqrt(3)`` in closed form (module docstring;
        the tables give it to 2 ulp).

        Args:
            u_dc: DC-link voltage, V.
        """
        if all(len(g) == 3 for g in self.layout.neutrals):
            return u_dc / np.sqrt(3.0)
        inv, _, bisectors = four_vector_tables(self.layout)
        total = np.sum(inv[0] @ np.concatenate([bisectors[0], np.zeros(2)]))
        return u_dc / total


class LargeVectorSVPWM(AbstractSectorSVPWM):
    """SVPWM with the two adjacent large vectors only (module docstring): the second plane's average is
    not controlled. Linear to ``|L| cos(pi/K) U_dc`` (peak, V).

    Args:
        layout: The winding (static), default five phases.
        name: The modulator's name in tables and figures (static).
    """

    layout: PhaseLayout = eqx.field(static=True, default=FIVE_PHASE)
    name: str = eqx.field(static=True, default="large-vector")

    def tables(self) -> tuple[np.ndarray, np.ndarray]:
        return large_vector_tables(self.layout)

    def linear_limit(self, u_dc):
        sv = space_vectors(self.layout)
        return sv.large_magnitude * np.cos(np.pi / len(sv.large)) * u_dc
