"""Reference frames: three-phase Clarke/Park (:mod:`.three_phase`, re-exported here) and the n-phase
vector space decomposition and double dq (:mod:`.multiphase`).
"""

from pmsmjax.frames.three_phase import (
    abc_to_alpha_beta,
    abc_to_alpha_beta_zero,
    abc_to_dq,
    alpha_beta_to_abc,
    dq_to_abc,
    inverse_park,
    park,
    rotation,
    wrap_angle,
)

__all__ = [
    "abc_to_alpha_beta",
    "abc_to_alpha_beta_zero",
    "wrap_angle",
    "alpha_beta_to_abc",
    "abc_to_dq",
    "dq_to_abc",
    "park",
    "inverse_park",
    "rotation",
]
