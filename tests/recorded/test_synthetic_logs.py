"""pmsmjax/studies/synthetic_logs.py: the two frames of one run agree through the inverse Park transform
written out here, and the noise has the documented size, independence and reproducibility."""

import numpy as np
import pytest

from pmsmjax import presets
from pmsmjax.recorded.synthetic_logs import LOG_COLUMNS, add_measurement_noise, drive_log, speed_scenario


@pytest.fixture(scope="module")
def logs():
    """40 ms of the book drive stepping to 1000 r/min, 10 N m at 20 ms, in both frames."""
    scenario = speed_scenario(1000.0, duration_s=0.04, load_time_s=0.02)
    drive = presets.book_drive()
    return {frame: drive_log(drive, scenario, frame=frame) for frame in LOG_COLUMNS}


def test_columns_and_truth(logs):
    for frame, log in logs.items():
        assert tuple(log) == LOG_COLUMNS[frame]
        assert all(v.dtype == np.float64 and v.shape == log["time"].shape for v in log.values())
    stator, dq = logs["alpha_beta"], logs["dq"]
    for name in ("time", "theta_e", "omega_m"):
        np.testing.assert_array_equal(stator[name], dq[name])
    assert dq["T_L"][0] == 0.0 and dq["T_L"][-1] == 10.0


def test_dq_log_is_the_stator_log_at_the_period_start_angle(logs):
    stator, dq = logs["alpha_beta"], logs["dq"]
    c, s = np.cos(dq["theta_e"]), np.sin(dq["theta_e"])
    for x in ("u", "i"):
        alpha = c * dq[f"{x}_d"] - s * dq[f"{x}_q"]
        beta = s * dq[f"{x}_d"] + c * dq[f"{x}_q"]
        scale = np.max(np.hypot(stator[f"{x}_alpha"], stator[f"{x}_beta"]))
        np.testing.assert_allclose(alpha, stator[f"{x}_alpha"], rtol=0, atol=1e-12 * scale)
        np.testing.assert_allclose(beta, stator[f"{x}_beta"], rtol=0, atol=1e-12 * scale)


def test_noise_size_independence_and_seed():
    n = 200_000
    rng = np.random.default_rng(0)
    log = {
        "time": np.arange(n) * 1e-4,
        "u_d": np.full(n, 30.0),
        "u_q": np.full(n, 40.0),  # RMS magnitude 50 V
        "i_d": np.zeros(n),
        "i_q": 2.0 * rng.choice([-1.0, 1.0], n),  # RMS magnitude 2 A
        "omega_m": np.ones(n),
    }
    levels = {("i_d", "i_q"): 0.01, ("u_d", "u_q"): 0.005}
    noisy = add_measurement_noise(log, levels, seed=4)
    for (a, b), sigma in ((("i_d", "i_q"), 0.02), (("u_d", "u_q"), 0.25)):
        for name in (a, b):
            assert np.std(noisy[name] - log[name]) == pytest.approx(sigma, rel=0.01)
    assert abs(np.corrcoef(noisy["u_d"] - log["u_d"], noisy["i_d"] - log["i_d"])[0, 1]) < 0.01
    np.testing.assert_array_equal(noisy["omega_m"], log["omega_m"])  # truth stays clean
    again = add_measurement_noise(log, levels, seed=4)
    assert all(np.array_equal(noisy[k], again[k]) for k in log)
    other = add_measurement_noise(log, levels, seed=5)
    assert not np.array_equal(noisy["u_d"], other["u_d"])
    # One level: the voltage pair, then the current pair, at that level.
    same = add_measurement_noise(log, 0.01, seed=4)
    expected = add_measurement_noise(log, {("u_d", "u_q"): 0.01, ("i_d", "i_q"): 0.01}, seed=4)
    assert all(np.array_equal(same[k], expected[k]) for k in log)
