"""The ``2^n`` switching states of an n-leg inverter feeding a multi-phase machine with isolated star points,
projected on the VSD planes, for any [`PhaseLayout`][pmsmjax.frames.multiphase.PhaseLayout] (the book, ch. 8
and 10; Zhao & Lipo, IEEE TIA 31(5), 1995, for the dual three-phase machine).

State index ``s = sum_x b_x 2^x`` (``b_x`` the upper switch of leg ``x``, leg order of the layout). Each
state's phase voltages are ``U_dc (b_x - mean of its star)``; their amplitude-invariant VSD gives one
vector per plane. [`space_vectors`][pmsmjax.inverters.multiphase_vectors.space_vectors] returns them with the
two groups of states that near-four-vector SVPWM uses
([`multiphase_svpwm`][pmsmjax.inverters.multiphase_svpwm]):

- **large** (L): the states of largest alpha-beta magnitude, one per direction, sorted by angle from
  the first at or after 0 rad; the sectors lie between neighbours (sector ``k`` from L_k to L_k+1);
- **second** (the next group collinear with L): at each L direction, the state of the next-largest
  alpha-beta magnitude. Its vector in the second plane is opposite to the L state's, so a mix of the two
  nulls that plane's average.

Six phases ([`SIX_PHASE`][pmsmjax.frames.multiphase.SIX_PHASE], two stars 30 deg apart), per unit of ``U_dc``:

==========  =====  ========================================  ===========  ==================
alpha-beta  count  name                                      z1-z2        direction
==========  =====  ========================================  ===========  ==================
0           4      zero (each star all-high or all-low)      0
0.1725      12     small                                     0.6440
1/3         24     medium                                    1/3
0.4714      12     medium-large (ML, the second group)       0.4714       collinear with L
0.6440      12     large (L), at 15 + 30 k deg               0.1725
==========  =====  ========================================  ===========  ==================

``|L| = (2/3) cos 15 deg``: an L state puts each star on one of its own hexagon's vertices, the two 30 deg
apart. 12 sectors of 30 deg, sector ``k`` between the L vectors at ``15 + 30 k`` and ``45 + 30 k`` deg.

Five phases ([`FIVE_PHASE`][pmsmjax.frames.multiphase.FIVE_PHASE]), per unit of ``U_dc``:

==========  =====  ========================================  ===========  ==================
alpha-beta  count  name                                      x-y          direction
==========  =====  ========================================  ===========  ==================
0           2      zero (00000, 11111)                       0
0.2472      10     small                                     0.6472
0.4000      10     medium (M, the second group)              0.4000       collinear with L
0.6472      10     large (L), at 36 k deg                    0.2472
==========  =====  ========================================  ===========  ==================

``|L| = (4/5) cos 36 deg``, ``|M| = 2/5``, ``|small| = (4/5) cos 72 deg``: the golden ratio links them
(``|L|/|M| = |M|/|small| = 1.618``).

All tables are NumPy float64 built once per layout (they must not depend on the JAX precision mode).
"""

import functools
import itertools
from typing import NamedTuple

import numpy as np

from pmsmjax.frames.multiphase import PhaseLayout, vsd_matrix
from pmsmjax.spec.validation import ParameterError

__all__ = ["SpaceVectors", "large_magnitude", "space_vectors"]


class SpaceVectors(NamedTuple):
    """Switching states of a layout (read-only NumPy float64).

    Attributes:
        states: ``(2^n, n)`` leg states.
        vectors: ``(2^n, 2 n_planes)`` their VSD voltages per unit of ``U_dc``.
        large: ``(K,)`` indices of the L states (``K`` sectors).
        second: ``(K,)`` indices of the next group at the same directions.
        bisectors: ``(K, 2)`` unit vectors halfway between L_k and L_k+1.
        large_magnitude: ``|L|`` per unit
            ([`large_magnitude`][pmsmjax.inverters.multiphase_vectors.SpaceVectors]).
    """

    states: np.ndarray
    vectors: np.ndarray
    large: np.ndarray
    second: np.ndarray
    bisectors: np.ndarray
    large_magnitude: float


def large_magnitude(layout: PhaseLayout, largest_in_table: float) -> float:
    """``|L|`` per unit of ``U_dc``: in closed form for two three-phase stars, else ``largest_in_table``.

    Two three-phase stars: an L state puts each star on a vertex of its own hexagon (``2/3`` in the star's
    frame, vertices every 60 deg from its first phase axis), the two vertices ``gap`` apart, the smallest
    angle between the two stars' vertex directions; the alpha-beta vector is their mean,
    ``(2/3) cos(gap/2)`` (six phases: ``(2/3) cos 15 deg``, which the table's magnitudes give to 1 ulp).

    Args:
        layout: The winding layout.
        largest_in_table: The largest magnitude in the layout's table, per unit.
    """
    if len(layout.neutrals) == 2 and all(len(g) == 3 for g in layout.neutrals):
        first, other = (layout.angles[g[0]] for g in layout.neutrals)
        offset = np.mod(other - first, np.pi / 3)
        gap = min(offset, np.pi / 3 - offset)
        return float((2.0 / 3.0) * np.cos(gap / 2))
    return float(largest_in_table)


@functools.lru_cache(maxsize=8)
def space_vectors(layout: PhaseLayout) -> SpaceVectors:
    """The switching-state tables of ``layout`` (module docstring).

    Args:
        layout: The winding layout.
    """
    layout.check()
    n = layout.n
    if n > 12:
        raise ParameterError(f"space_vectors enumerates 2^n states; n = {n} is too many.")
    states = np.array(list(itertools.product((0, 1), repeat=n)), dtype=float)[:, ::-1]  # leg 0 = bit 0
    phase = states.copy()
    for group in layout.neutrals:
        idx = list(group)
        phase[:, idx] -= phase[:, idx].mean(axis=1, keepdims=True)
    vectors = phase @ vsd_matrix(layout)[: layout.n_active].T
    mag = np.hypot(vectors[:, 0], vectors[:, 1])
    ang = np.mod(np.arctan2(vectors[:, 1], vectors[:, 0]), 2 * np.pi)
    tol = 1e-9
    large_mag = mag.max()
    large = np.nonzero(np.abs(mag - large_mag) < tol)[0]
    # Angles within tol of 2 pi are the direction 0.
    key = np.where(ang[large] > 2 * np.pi - tol, 0.0, ang[large])
    large = large[np.argsort(key)]
    second = []
    for i in large:
        same = (np.abs(np.angle(np.exp(1j * (ang - ang[i])))) < tol) & (mag < large_mag - tol) & (mag > tol)
        if not np.any(same):
            raise ParameterError(f"layout {layout.name!r}: no state is collinear with the large vector {i}.")
        m2 = mag[same].max()
        (j,) = np.nonzero(same & (np.abs(mag - m2) < tol))
        if len(j) != 1:
            raise ParameterError(
                f"layout {layout.name!r}: {len(j)} states share the second magnitude at one L direction; "
                "near-four-vector tables need exactly one."
            )
        second.append(int(j[0]))
    unit = vectors[large, :2] / large_mag
    mid = unit + np.roll(unit, -1, axis=0)
    bisectors = mid / np.linalg.norm(mid, axis=1, keepdims=True)
    magnitude = large_magnitude(layout, large_mag)
    out = SpaceVectors(states, vectors, large, np.array(second), bisectors, magnitude)
    for a in out[:5]:
        a.setflags(write=False)
    return out
