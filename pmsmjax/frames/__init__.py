"""Reference frames: three-phase Clarke/Park ([`three_phase`][pmsmjax.frames.three_phase], re-exported here)
and the n-phase vector space decomposition and double dq ([`multiphase`][pmsmjax.frames.multiphase]).
"""

from pmsmjax.frames import three_phase
from pmsmjax.frames.three_phase import *  # noqa: F403 (its __all__ is the list re-exported here)

__all__ = list(three_phase.__all__)
