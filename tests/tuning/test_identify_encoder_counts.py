"""An incremental encoder's count as the angle input of an identification log
(tuning.identify.log_columns.angle_from_counts, the encoder_counts column).

The identification log is not the engine's: the reference drive of tuning/identify/reference_log.py (NumPy
closed loop, motor integrated by SciPy's solve_ivp) on ID_TEST_MOTOR, 0.4 s through four speed levels, its
signals given in the stator frame so that the angle matters (they are turned into dq with it). The count is
that of a 2500-line encoder whose index sits half a count before the d axis (so the count is the nearest one),
read from a 16-bit counter that wraps.
"""

import numpy as np
import pytest

from pmsmjax.cli import main
from pmsmjax.io.logs import write_csv_atomic
from pmsmjax.recorded.synthetic_logs import ID_LOG_NOISE, ID_TEST_MOTOR, add_measurement_noise
from pmsmjax.spec.validation import ParameterError
from tuning.identify import IdentifyOptions, identify
from tuning.identify.log import drive_log_from_columns
from tuning.identify.log_columns import angle_from_counts
from tuning.identify.reference_log import reference_drive_log

P, LINES = 4, 2500
NAMES = ("R", "L_d", "L_q", "psi_f", "J", "B")


def _wrap(x):
    return np.mod(x + np.pi, 2 * np.pi) - np.pi


def _counts(theta_e_unwrapped, lines=LINES, bits=16, revolutions=6):
    """The counter's reading (unsigned, ``bits`` wide) for an unwrapped electrical angle, rad, after the
    rotor has turned ``revolutions`` whole turns from the index (so the 16-bit counter soon wraps)."""
    return np.mod(
        np.round(theta_e_unwrapped / P / (2 * np.pi) * 4 * lines) + 4 * lines * revolutions, 2**bits
    )


def test_counts_give_the_angle_within_half_a_count():
    t = np.arange(20001) * 1e-4
    th_m = 150.0 * t + 60.0 * np.sin(2 * np.pi * 2.0 * t)  # mechanical rad: turns back and forth
    count = np.round(th_m / (2 * np.pi) * 4 * LINES)
    assert np.ptp(count) > 4 * 2**16  # the 16-bit counter wraps several times, both ways
    half = P * 2 * np.pi / (4 * LINES) / 2  # half a count, electrical rad
    truth = _wrap(P * th_m)
    for raw, bits in (
        (np.mod(count, 2**16), None),  # unsigned, wrap detected
        (np.mod(count + 2**15, 2**16) - 2**15, None),  # signed, wrap detected
        (np.mod(count, 2**16), 16),  # width given
        (count, None),  # a count that never wraps (a 64-bit software counter)
    ):
        th = angle_from_counts(raw, LINES, P, counter_bits=bits)
        assert np.all(th > -np.pi) and np.all(th <= np.pi)
        assert np.max(np.abs(_wrap(th - truth))) <= half + 1e-9


@pytest.fixture(scope="module")
def stator_log():
    run = reference_drive_log(
        ID_TEST_MOTOR, u_dc_v=300.0, Ts=1e-4, max_current_a=15.0, current_bandwidth_rad_s=2000.0,
        speed_bandwidth_rad_s=60.0, speeds_rpm=(500, 1200, -400, 800), duration_s=0.4, id_amplitude_a=3.0,
        prbs_clock_s=0.005,
    )  # fmt: skip
    noisy = add_measurement_noise(run, ID_LOG_NOISE, seed=0)
    th = run["theta_e"]  # unwrapped electrical angle from 0: the d axis at the encoder's index
    c, s = np.cos(th), np.sin(th)
    cols = {"time": noisy["time"], "omega_m": noisy["omega_m"]}
    for x in ("u", "i"):
        d, q = noisy[f"{x}_d"], noisy[f"{x}_q"]
        cols[f"{x}_alpha"], cols[f"{x}_beta"] = c * d - s * q, s * d + c * q
    return cols, th


def test_identify_on_counts_gives_the_parameters_of_the_angle(stator_log):
    """Each value from the count inside the 95 % interval of the value from the angle, and the other way
    round."""
    cols, th = stator_log
    with_angle = drive_log_from_columns({**cols, "theta_e": _wrap(th)}, P, hold="stator")
    with_counts = drive_log_from_columns({**cols, "encoder_counts": _counts(th)}, P, hold="stator",
                                         encoder_lines=LINES)  # fmt: skip
    assert any("from encoder_counts" in n and "16-bit" in n for n in with_counts.notes)
    a = identify(with_angle, IdentifyOptions(pole_pairs=P)).summary["parameters"]
    b = identify(with_counts, IdentifyOptions(pole_pairs=P)).summary["parameters"]
    for n in NAMES:
        assert a[n]["ci95"][0] < b[n]["value"] < a[n]["ci95"][1], (n, a[n], b[n])
        assert b[n]["ci95"][0] < a[n]["value"] < b[n]["ci95"][1], (n, a[n], b[n])
        assert abs(a[n]["value"] / ID_TEST_MOTOR[n] - 1) < 0.1, n


def test_counts_are_refused_without_lines_or_beside_an_angle(stator_log, tmp_path, capsys):
    cols, th = stator_log
    counts = _counts(th)
    with pytest.raises(ParameterError, match=r"--encoder-lines N .* \[sensor\] lines"):
        drive_log_from_columns({**cols, "encoder_counts": counts}, P)
    with pytest.raises(ParameterError, match="both theta_e and encoder_counts"):
        drive_log_from_columns(
            {**cols, "encoder_counts": counts, "theta_e": _wrap(th)}, P, encoder_lines=LINES
        )
    # Two captures of a counter that wraps at 65536, not a whole number of revolutions (10000 counts).
    keep = np.r_[0:1500, 2500:4000]
    burst = {k: v[keep] for k, v in {**cols, "encoder_counts": counts}.items()}
    with pytest.raises(ParameterError, match="not a whole number of revolutions"):
        drive_log_from_columns(burst, P, encoder_lines=LINES, counter_bits=16)
    write_csv_atomic(tmp_path / "log.csv", {**cols, "encoder_counts": counts})
    status = main(["identify", str(tmp_path / "log.csv"), "--pole-pairs", "4", "--out", str(tmp_path / "o")])
    assert status == 2 and "--encoder-lines" in capsys.readouterr().err
