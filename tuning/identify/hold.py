"""Which voltage hold a log follows (``pmsmjax identify --hold auto``, the default).

A log's voltage of row k is held until row k+1 either in the stator frame (a real inverter) or in the
rotor frame (a dq-model simulator); see [`pmsmjax.recorded.replay`][pmsmjax.recorded.replay]. Read with the
wrong one, every voltage is turned by about ``omega_e dt / 2``: the fit then returns biased values (R 2 % off,
psi_f 1 % off on the test logs) or fails. Both are cheap to try: the equation-error warm start of
[`tuning.identify.electrical.warm_start`][tuning.identify.electrical.warm_start] is a linear least-squares
fit, and the share of the integrated voltage it leaves unexplained is about ten times larger for the wrong
hold at speed (tests/tuning/test_identify_honesty.py). The hold leaving less unexplained is chosen; when the
two differ by less than [`AMBIGUOUS_RATIO`][tuning.identify.hold.AMBIGUOUS_RATIO] (a log at low speed, where
the holds coincide) either fits and the choice is noted as such.
"""

import dataclasses

from tuning.identify import electrical as el

__all__ = ["detect_hold", "AMBIGUOUS_RATIO"]

#: Below this ratio of the two unexplained shares the log does not tell the holds apart.
AMBIGUOUS_RATIO = 1.5


def detect_hold(log, pole_pairs: int, fixed: dict | None = None, dead_time: bool = False):
    """``(log with the hold that fits better, {"stator": unexplained, "rotor": unexplained}, note)``.

    `log`: a [`tuning.identify.log.DriveLog`][tuning.identify.log.DriveLog] (its own ``hold`` is ignored);
    `fixed`: electrical parameters held fixed in the fit (SI).
    """
    fixed = {k: v for k, v in (fixed or {}).items() if k in el.ELECTRICAL_NAMES}
    unexplained = {}
    for hold in ("stator", "rotor"):
        _, explained = el.warm_start(log, pole_pairs, hold, fixed, dead_time)
        unexplained[hold] = max(1.0 - explained, 1e-300)
    best = min(unexplained, key=unexplained.get)
    other = "rotor" if best == "stator" else "stator"
    ratio = unexplained[other] / unexplained[best]
    if ratio < AMBIGUOUS_RATIO:
        note = (
            f"hold: {best} (auto; the log does not tell the holds apart, unexplained voltage "
            f"{unexplained[best]:.2e} against {unexplained[other]:.2e}: they agree at its speeds)"
        )
    else:
        note = (
            f"hold: {best} (auto; the {other} hold leaves {ratio:.1f}x more of the voltage unexplained, "
            f"{unexplained[other]:.2e} against {unexplained[best]:.2e})"
        )
    return dataclasses.replace(log, hold=best, notes=log.notes + (note,)), unexplained, note
