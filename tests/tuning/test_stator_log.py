"""The observers' stator-frame log (tuning/identify/stator_log.py) from columns an instrument records:
phase quantities become alpha-beta by the amplitude-invariant Clarke transform (written out here, not
the package's), and voltages logged in dq, which need the angle an observer is to estimate, are refused
in one line."""

import numpy as np
import pytest

from pmsmjax.spec.validation import ParameterError
from tuning.identify.stator_log import stator_log_from_columns

N, TS = 200, 1e-4


def _phases(amplitude, phase):
    w = 2 * np.pi * 50.0
    t = np.arange(N) * TS
    return t, [amplitude * np.cos(w * t + phase - k * 2 * np.pi / 3) for k in range(3)]


def test_phase_columns_become_alpha_beta():
    t, (i_a, i_b, i_c) = _phases(4.0, 0.3)
    _, (u_a, u_b, u_c) = _phases(60.0, 1.1)
    log = stator_log_from_columns(
        {"time": t, "i_a": i_a, "i_b": i_b, "i_c": i_c, "u_a": u_a, "u_b": u_b, "u_c": u_c}
    )
    clarke = lambda a, b, c: np.stack([(2 * a - b - c) / 3, (b - c) / np.sqrt(3)], axis=1)
    np.testing.assert_allclose(log.i_ab, clarke(i_a, i_b, i_c), rtol=0, atol=1e-12)
    np.testing.assert_allclose(log.u_ab, clarke(u_a, u_b, u_c), rtol=0, atol=1e-10)
    assert log.Ts == pytest.approx(TS) and log.n == N
    np.testing.assert_allclose(np.hypot(*log.i_ab.T), 4.0, rtol=1e-12)  # amplitude-invariant


def test_dq_voltages_are_refused_in_one_line():
    t, (i_a, i_b, i_c) = _phases(4.0, 0.3)
    cols = {"time": t, "i_a": i_a, "i_b": i_b, "i_c": i_c, "u_d": i_a, "u_q": i_b}
    with pytest.raises(ParameterError, match=r"voltages are logged in dq \(u_d, u_q\)") as err:
        stator_log_from_columns(cols)
    assert "\n" not in str(err.value)
