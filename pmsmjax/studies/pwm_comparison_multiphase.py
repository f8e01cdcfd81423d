"""Former names of the six- and five-phase PWM comparison, now one procedure for any phase count in
:mod:`pmsmjax.studies.pwm_comparison`: ``SixPhaseCompareSettings(...)`` is
``CompareSettings(phases=6, ...)`` (give ``phases=5`` for five phases) and ``compare_six_phase`` is
``compare``. Kept so that existing imports run; new code imports :mod:`pmsmjax.studies.pwm_comparison`.
"""

from pmsmjax.studies.pwm_comparison import CompareSettings
from pmsmjax.studies.pwm_comparison import compare as compare_six_phase

__all__ = ["SixPhaseCompareSettings", "compare_six_phase"]


def SixPhaseCompareSettings(**fields) -> CompareSettings:  # noqa: N802 (the former class's name)
    """:class:`~pmsmjax.studies.pwm_comparison.CompareSettings` with ``phases=6`` unless given."""
    return CompareSettings(**{"phases": 6, **fields})
