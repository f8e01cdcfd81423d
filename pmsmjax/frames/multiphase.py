"""Multi-phase reference frames: vector space decomposition (VSD) of n phases, and the six-phase double dq
(the book, ch. 7); the five-phase layout of chapter 10.

**Phase layout.** A machine's windings are described by a
[`PhaseLayout`][pmsmjax.frames.multiphase.PhaseLayout]: the angle of each phase's magnetic axis (rad, from the
A axis), the groups of phases that share an isolated star point, and the harmonic order of each
two-dimensional subspace of the VSD. [`SIX_PHASE`][pmsmjax.frames.multiphase.SIX_PHASE] is the dual
three-phase winding of chapter 7: sets ABC at 0, 120, 240 deg and UVW at 30, 150, 270 deg, two isolated
neutrals, subspaces alpha-beta (order 1) and z1-z2 (order 5).
[`FIVE_PHASE`][pmsmjax.frames.multiphase.FIVE_PHASE] is the symmetrical five-phase winding of chapter 10:
phases A..E at ``72 k`` deg, one star point, subspaces alpha-beta (order 1) and x-y (order 3), so the 5x5 VSD
is the five-phase Clarke (rows alpha, beta, x, y, zero sequence).

**VSD** (Zhao & Lipo, "Space vector PWM control of dual three-phase induction machine using vector space
decomposition", IEEE TIA 31(5), 1995). Row pairs ``(2/n) [cos(h g_k), sin(h g_k)]`` for each harmonic
order ``h`` of the layout, then one row per star point: the mean of its phases (its zero sequence)::

    alpha = 1/3 sum_k cos(g_k) x_k,   beta = 1/3 sum_k sin(g_k) x_k          (six phases: 2/n = 1/3)
    z1    = 1/3 sum_k cos(5 g_k) x_k, z2   = 1/3 sum_k sin(5 g_k) x_k
    o1    = (x_A + x_B + x_C)/3,      o2   = (x_U + x_V + x_W)/3

Amplitude-invariant (default, as the three-phase Clarke): a balanced set ``x_k = X cos(th - g_k)`` gives
``|alpha + j beta| = X``; with three phases and order 1 this is exactly
[`pmsmjax.frames.abc_to_alpha_beta_zero`][pmsmjax.frames.three_phase.abc_to_alpha_beta_zero].
``power_invariant=True`` scales every row to unit length (an orthogonal matrix). The rows are mutually
orthogonal (checked when the matrix is built), so the inverse is ``T^T diag(1/|row|^2)`` exactly: no
numerical inversion.

Why order 5 for z1-z2: for ABC, ``5 g = -g`` modulo 2 pi, and for UVW ``5 g = pi - g``; hence
``z1 + j z2 = conj(x_ab1 - x_ab2)/2`` with ``x_ab1``, ``x_ab2`` the Clarke vectors of the two sets in
the common stationary frame, while ``alpha + j beta = (x_ab1 + x_ab2)/2``. The 5th and 7th harmonics
(orders ``6k -+ 1``, k odd) of the phase quantities map into z1-z2 and produce no torque.

**Double dq.** Each set gets its own Park transform: set ABC at ``th``, set UVW (whose own alpha axis is
the U axis at pi/6) at ``th - pi/6``, so both dq frames are aligned with the rotor: ``[d1, q1, d2, q2]``.

**The linear relation** (derived from the two identities above): with the z1-z2 vector seen from a frame
that rotates *backwards* with the rotor, ``z' = e^{j th} (z1 + j z2)``
([`z_to_counter_rotating`][pmsmjax.frames.multiphase.z_to_counter_rotating])::

    [d, q, z'_d, z'_q] = M [d1, q1, d2, q2]
    M = 1/2 [[1, 0, 1, 0], [0, 1, 0, 1], [1, 0, -1, 0], [0, -1, 0, 1]]

i.e. ``dq = (dq1 + dq2)/2`` and ``z'_d + j z'_q = conj(dq1 - dq2)/2``; ``M^-1 = 2 M^T``. A constant
matrix: the double-dq and VSD descriptions are the same coordinates, the z subspace taken in the
counter-rotating frame (book 9.5). Fundamental-frequency unbalance between the two sets is a constant
``z'`` (a negative-sequence z1-z2 vector at the electrical frequency).

All functions act on the last axis and broadcast over leading axes.
"""

import functools
import math
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from pmsmjax._types import Array, ArrayLike
from pmsmjax.frames.three_phase import abc_to_alpha_beta, alpha_beta_to_abc, inverse_park, park
from pmsmjax.spec.validation import ParameterError

__all__ = [
    "PhaseLayout",
    "SIX_PHASE",
    "FIVE_PHASE",
    "DOUBLE_DQ_TO_VSD",
    "VSD_TO_DOUBLE_DQ",
    "vsd_matrix",
    "inverse_vsd_matrix",
    "vsd",
    "inverse_vsd",
    "double_dq",
    "inverse_double_dq",
    "double_dq_to_vsd",
    "vsd_to_double_dq",
    "z_to_counter_rotating",
    "z_from_counter_rotating",
]


class PhaseLayout(NamedTuple):
    """Geometry of an n-phase winding (static configuration: hashable, compared by value).

    - `angles`: ``(n,)`` magnetic-axis angle of each phase, rad, in the order of the inverter legs.
    - `neutrals`: groups of phase indices sharing one isolated star point (one zero-sequence row each).
    - `harmonics`: the order ``h`` of each two-dimensional VSD subspace, the fundamental (1) first.
    - `name`: for messages.

    ``2 len(harmonics) + len(neutrals) == n``.
    """

    angles: tuple[float, ...]
    neutrals: tuple[tuple[int, ...], ...]
    harmonics: tuple[int, ...]
    name: str = ""

    @property
    def n(self) -> int:
        """Number of phases (inverter legs)."""
        return len(self.angles)

    @property
    def n_planes(self) -> int:
        """Number of two-dimensional subspaces (alpha-beta first)."""
        return len(self.harmonics)

    @property
    def n_active(self) -> int:
        """Components that isolated star points leave free: ``2 n_planes`` (the zero sequences are 0)."""
        return 2 * len(self.harmonics)

    def check(self) -> None:
        """Raise [`ParameterError`][pmsmjax.spec.validation.ParameterError] unless the layout is consistent:
        ``2 n_planes + n_stars == n`` and the star-point groups cover every phase once."""
        n = self.n
        if 2 * len(self.harmonics) + len(self.neutrals) != n:
            raise ParameterError(
                f"phase layout {self.name!r}: {n} phases need 2 x planes + star points = {n}, got "
                f"{len(self.harmonics)} planes and {len(self.neutrals)} star points."
            )
        members = sorted(i for g in self.neutrals for i in g)
        if members != list(range(n)):
            raise ParameterError(
                f"phase layout {self.name!r}: the star-point groups must cover each phase once, got "
                f"{self.neutrals}."
            )


#: The dual three-phase (asymmetrical six-phase) winding: A, B, C at 0, 120, 240 deg; U, V, W at 30, 150,
#: 270 deg; two isolated neutrals; subspaces alpha-beta and z1-z2 (order 5).
SIX_PHASE = PhaseLayout(
    angles=(0.0, 2 * math.pi / 3, 4 * math.pi / 3, math.pi / 6, 5 * math.pi / 6, 3 * math.pi / 2),
    neutrals=((0, 1, 2), (3, 4, 5)),
    harmonics=(1, 5),
    name="six-phase (dual three-phase, 30 deg)",
)

#: The symmetrical five-phase winding (the book, ch. 10): A, B, C, D, E at 0, 72, 144, 216, 288 deg, one
#: isolated star point; subspaces alpha-beta (fundamental, order 1) and x-y (order 3). Phase harmonics of
#: orders ``5k +- 1`` map into alpha-beta, ``5k +- 2`` (3, 7, 13, ...) into x-y, multiples of 5 into the
#: zero sequence (no current with an isolated star).
FIVE_PHASE = PhaseLayout(
    angles=tuple(2 * math.pi * k / 5 for k in range(5)),
    neutrals=((0, 1, 2, 3, 4),),
    harmonics=(1, 3),
    name="five-phase (72 deg)",
)


@functools.lru_cache(maxsize=32)
def vsd_matrix(layout: PhaseLayout = SIX_PHASE, power_invariant: bool = False) -> np.ndarray:
    """The ``(n, n)`` VSD matrix (NumPy float64, read-only, cached per layout): harmonic row pairs, then one
    zero-sequence row per star point. Raises if the rows are not mutually orthogonal (a layout whose
    subspaces are not independent)."""
    layout.check()
    g = np.asarray(layout.angles, dtype=float)
    n = layout.n
    rows = []
    for h in layout.harmonics:
        rows += [np.cos(h * g), np.sin(h * g)]
    rows = [(2.0 / n) * r for r in rows]
    for group in layout.neutrals:
        r = np.zeros(n)
        r[list(group)] = 1.0 / len(group)
        rows.append(r)
    T = np.stack(rows)
    if power_invariant:
        T = T / np.linalg.norm(T, axis=1, keepdims=True)
    gram = T @ T.T
    off = gram - np.diag(np.diag(gram))
    if np.max(np.abs(off)) > 1e-12 * np.max(np.diag(gram)):
        raise ParameterError(
            f"phase layout {layout.name!r}: the VSD rows are not orthogonal; choose harmonic orders whose "
            "subspaces are independent for these phase angles."
        )
    T.setflags(write=False)
    return T


@functools.lru_cache(maxsize=32)
def inverse_vsd_matrix(layout: PhaseLayout = SIX_PHASE, power_invariant: bool = False) -> np.ndarray:
    """``T^-1 = T^T diag(1/|row|^2)`` of [`vsd_matrix`][pmsmjax.frames.multiphase.vsd_matrix] (exact for
    orthogonal rows), ``(n, n)``."""
    T = vsd_matrix(layout, power_invariant)
    T_inv = T.T / np.sum(T * T, axis=1)[None, :]
    T_inv.setflags(write=False)
    return T_inv


def vsd(x_phase: ArrayLike, layout: PhaseLayout = SIX_PHASE, power_invariant: bool = False) -> Array:
    """Phase quantities ``(..., n)`` -> VSD components ``(..., n)``: [alpha, beta, z1, z2, ..., o1, o2]."""
    x = jnp.asarray(x_phase)
    if x.shape[-1] != layout.n:
        raise ParameterError(f"vsd: expected {layout.n} phases on the last axis, got shape {x.shape}.")
    return x @ jnp.asarray(vsd_matrix(layout, power_invariant).T, x.dtype)


def inverse_vsd(x_vsd: ArrayLike, layout: PhaseLayout = SIX_PHASE, power_invariant: bool = False) -> Array:
    """VSD components -> phase quantities ``(..., n)``.

    ``x_vsd``: ``(..., n)`` with the zero sequences, or ``(..., 2 n_planes)`` without them (taken as 0:
    isolated star points).
    """
    x = jnp.asarray(x_vsd)
    T_inv = inverse_vsd_matrix(layout, power_invariant)
    m = x.shape[-1]
    if m not in (layout.n, layout.n_active):
        raise ParameterError(
            f"inverse_vsd: expected {layout.n} or {layout.n_active} components on the last axis, got {m}."
        )
    return x @ jnp.asarray(T_inv[:, :m].T, x.dtype)


# --- six phases: double dq and its relation to the VSD ------------------------------------------------
_SET2_SHIFT = math.pi / 6  # the UVW set's magnetic axes lead ABC by 30 degrees


def double_dq(x_phase: ArrayLike, theta_e: ArrayLike) -> Array:
    """Six phase quantities ``(..., 6)`` -> ``(..., 4)`` [d1, q1, d2, q2]: each three-phase set through its
    own (amplitude-invariant) Clarke and its own Park at ``theta_e`` (ABC) and ``theta_e - pi/6`` (UVW)."""
    x = jnp.asarray(x_phase)
    if x.shape[-1] != 6:
        raise ParameterError(f"double_dq: expected 6 phases on the last axis, got shape {x.shape}.")
    theta = jnp.asarray(theta_e)
    dq1 = park(abc_to_alpha_beta(x[..., :3]), theta)
    dq2 = park(abc_to_alpha_beta(x[..., 3:]), theta - _SET2_SHIFT)
    return jnp.concatenate([dq1, dq2], axis=-1)


def inverse_double_dq(x_dd: ArrayLike, theta_e: ArrayLike) -> Array:
    """``(..., 4)`` [d1, q1, d2, q2] -> ``(..., 6)`` phase quantities (each set's zero sequence 0)."""
    x = jnp.asarray(x_dd)
    theta = jnp.asarray(theta_e)
    abc = alpha_beta_to_abc(inverse_park(x[..., :2], theta))
    uvw = alpha_beta_to_abc(inverse_park(x[..., 2:4], theta - _SET2_SHIFT))
    return jnp.concatenate([abc, uvw], axis=-1)


#: ``[d, q, z'_d, z'_q] = DOUBLE_DQ_TO_VSD @ [d1, q1, d2, q2]`` (module docstring), NumPy float64.
DOUBLE_DQ_TO_VSD = 0.5 * np.array(
    [[1.0, 0.0, 1.0, 0.0], [0.0, 1.0, 0.0, 1.0], [1.0, 0.0, -1.0, 0.0], [0.0, -1.0, 0.0, 1.0]]
)
#: Its inverse, ``2 M^T``: ``d1 = d + z'_d``, ``q1 = q - z'_q``, ``d2 = d - z'_d``, ``q2 = q + z'_q``.
VSD_TO_DOUBLE_DQ = 2.0 * DOUBLE_DQ_TO_VSD.T


def z_to_counter_rotating(x_z: ArrayLike, theta_e: ArrayLike) -> Array:
    """z1-z2 ``(..., 2)`` seen from the frame rotating at ``-theta_e``: ``e^{j th} (z1 + j z2)``."""
    return inverse_park(x_z, theta_e)


def z_from_counter_rotating(x_zc: ArrayLike, theta_e: ArrayLike) -> Array:
    """Inverse of [`z_to_counter_rotating`][pmsmjax.frames.multiphase.z_to_counter_rotating]:
    ``e^{-j th} (z'_d + j z'_q)``, ``(..., 2)``."""
    return park(x_zc, theta_e)


def double_dq_to_vsd(x_dd: ArrayLike, theta_e: ArrayLike) -> Array:
    """``(..., 4)`` [d1, q1, d2, q2] -> ``(..., 4)`` [d, q, z1, z2] (z1-z2 in the stationary frame)."""
    x = jnp.asarray(x_dd)
    y = x @ jnp.asarray(DOUBLE_DQ_TO_VSD.T, x.dtype)
    return jnp.concatenate([y[..., :2], z_from_counter_rotating(y[..., 2:], theta_e)], axis=-1)


def vsd_to_double_dq(x_vsd_dq: ArrayLike, theta_e: ArrayLike) -> Array:
    """``(..., 4)`` [d, q, z1, z2] (z1-z2 stationary) -> ``(..., 4)`` [d1, q1, d2, q2]."""
    x = jnp.asarray(x_vsd_dq)
    y = jnp.concatenate([x[..., :2], z_to_counter_rotating(x[..., 2:4], theta_e)], axis=-1)
    return y @ jnp.asarray(VSD_TO_DOUBLE_DQ.T, y.dtype)
