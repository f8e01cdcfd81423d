"""``replay`` on a drive file with a flux map runs the map's saturated plant: a log of the analytic
saturated machine behind the preset ``saturated-ipm`` map, made by SciPy under a NumPy current loop
(:mod:`tuning.identify.saturated_reference_log`, no code of the engine), is replayed open loop from its
recorded voltages and followed to the map's resolution; the same file's linear model misses it."""

import numpy as np

from pmsmjax.io.logs import write_csv_atomic
from pmsmjax.recorded.replay import replay_file
from tuning.identify.saturated_reference_log import SATURATED_IPM, operating_walk, saturated_drive_log


def test_replay_follows_a_scipy_log_of_the_saturated_machine(tmp_path):
    walk = operating_walk([-8.0, 0.0], [-8.0, 0.0, 8.0])  # 12 operating points, 4 ms each, 1000 r/min
    log = saturated_drive_log(SATURATED_IPM, walk, speed_rpm=1000.0, dwell_s=4e-3, rtol=1e-10)
    write_csv_atomic(tmp_path / "log.csv", log)
    replayed = replay_file(tmp_path / "log.csv", "saturated-ipm", tmp_path / "map", hold="stator")
    out = np.genfromtxt(replayed, delimiter=",", names=True)
    peak = np.abs(log["i_q"]).max()
    error = max(np.abs(out["i_d"] - log["i_d"]).max(), np.abs(out["i_q"] - log["i_q"]).max()) / peak
    # 41 x 41 points 1.5 A apart: the interpolant's error (0.19 % measured; a 0.375 A grid of the same model
    # gives 0.035 %)
    assert error < 3e-3
    # the linear L_d, L_q, psi_f the same file implies (at the rated current) cannot follow it
    linear = tmp_path / "linear.toml"
    linear.write_text(
        "[motor]\nR = 0.5\nL_d = 0.00398\nL_q = 0.00278\npsi_f = 0.1\npole_pairs = 4\nJ = 0.002\nB = 0.001\n"
    )
    out = np.genfromtxt(
        replay_file(tmp_path / "log.csv", linear, tmp_path / "lin", hold="stator"), delimiter=",", names=True
    )
    assert np.abs(out["i_q"] - log["i_q"]).max() / peak > 0.2
