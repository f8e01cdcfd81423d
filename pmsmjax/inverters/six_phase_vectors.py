"""The 64 switching states of a six-leg inverter feeding a dual three-phase machine (two isolated stars),
projected on alpha-beta and z1-z2 (BOOK.md chapter 8; Zhao & Lipo, IEEE TIA 31(5), 1995).

State index ``s = sum_x b_x 2^x`` with ``b_x`` the upper switch of leg ``x`` in the order A, B, C, U, V,
W. Each state's phase voltages are ``U_dc (b_x - mean of its star)``; their VSD (amplitude-invariant,
:func:`pmsmjax.frames.multiphase.vsd`) gives one alpha-beta and one z1-z2 vector. Per unit of ``U_dc``:

============  =====  ==========================================  ===========
alpha-beta    count  name                                         z1-z2
============  =====  ==========================================  ===========
0             4      zero (each star all-high or all-low)         0
0.1725        12     small                                        0.6440
1/3           24     medium                                       1/3
0.4714        12     medium-large (ML), collinear with L           0.4714
0.6440        12     large (L), at 15 + 30 k deg                   0.1725
============  =====  ==========================================  ===========

``|L| = (2/3) cos 15 deg``: an L state puts each star on one of its own largest vectors, 30 deg apart.
The ML vector at an L vector's angle has its z1-z2 component opposite to the L vector's, which is what
lets four-vector SVPWM null the z1-z2 average. Sectors: 12 of 30 deg, sector ``k`` between the L vectors
at ``15 + 30 k`` and ``45 + 30 k`` deg, found as the largest projection of the reference on the sector
bisectors ``30 + 30 k`` deg.

All tables are NumPy float64 built at import (they must not depend on the JAX precision mode).
"""

import itertools

import numpy as np

from pmsmjax.frames.multiphase import SIX_PHASE, vsd_matrix

__all__ = [
    "STATES",
    "VECTORS",
    "LARGE",
    "MEDIUM_LARGE",
    "BISECTORS",
    "LARGE_MAGNITUDE",
    "switching_vectors",
]


def _tables():
    states = np.array(list(itertools.product((0, 1), repeat=6)), dtype=float)[:, ::-1]  # leg A = bit 0
    phase = states.copy()
    for group in SIX_PHASE.neutrals:
        idx = list(group)
        phase[:, idx] -= phase[:, idx].mean(axis=1, keepdims=True)
    vectors = phase @ vsd_matrix(SIX_PHASE)[:4].T
    mag = np.hypot(vectors[:, 0], vectors[:, 1])
    ang = np.arctan2(vectors[:, 1], vectors[:, 0])
    large_mag = (2.0 / 3.0) * np.cos(np.pi / 12)
    large, medium_large = [], []
    for k in range(12):
        a = np.pi / 12 + k * np.pi / 6
        same_angle = np.abs(np.angle(np.exp(1j * (ang - a)))) < 1e-9
        (i_l,) = np.nonzero(same_angle & np.isclose(mag, large_mag, atol=1e-12))
        (i_ml,) = np.nonzero(same_angle & np.isclose(mag, np.sqrt(2.0) / 3.0, atol=1e-12))
        assert len(i_l) == 1 and len(i_ml) == 1, "each L angle has one L and one ML state"
        large.append(int(i_l[0]))
        medium_large.append(int(i_ml[0]))
    bis = np.pi / 6 + np.arange(12) * np.pi / 6
    return states, vectors, np.array(large), np.array(medium_large), np.stack([np.cos(bis), np.sin(bis)], 1)


#: ``(64, 6)`` leg states (1 = upper switch on); ``(64, 4)`` their [alpha, beta, z1, z2] voltages per
#: unit of ``U_dc``; indices ``(12,)`` of the L and ML states at ``15 + 30 k`` deg; ``(12, 2)`` unit
#: vectors of the sector bisectors.
STATES, VECTORS, LARGE, MEDIUM_LARGE, BISECTORS = _tables()
#: ``|L| = (2/3) cos(15 deg)`` per unit of ``U_dc``.
LARGE_MAGNITUDE = (2.0 / 3.0) * np.cos(np.pi / 12)
for _a in (STATES, VECTORS, LARGE, MEDIUM_LARGE, BISECTORS):
    _a.setflags(write=False)


def switching_vectors(u_dc: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """``(states (64, 6), vectors (64, 4) V)``: every switching state and its [alpha, beta, z1, z2]
    voltage at DC-link voltage ``u_dc`` (V)."""
    return STATES.copy(), u_dc * VECTORS
