"""Stator-frame drive logs made by this project's own drive, with measurement noise: what the chapter 5
observers are tested, benchmarked and tuned on (``pmsmjax observe`` reads the same layout from files).

A log holds, per control period ``t_k``: the stator-frame voltage applied over ``[t_k, t_{k+1})`` (the
period average of the applied duties, which the averaged bridge applies exactly) and the currents
sampled at ``t_k`` (columns ``time, u_alpha, u_beta, i_alpha, i_beta``), plus the true electrical angle
and mechanical speed (``theta_e``, ``omega_m``) to score an observer against.

Noise (:func:`add_measurement_noise`): white Gaussian, standard deviation ``level`` times the RMS of the
vector's magnitude over the log, the same on both axes, independently on the voltages and on the
currents (the convention of ``tuning/identify/synthetic_log.py``); the truth columns stay noise-free.
"""

import numpy as np

from pmsmjax.drive import Drive
from pmsmjax.frames.three_phase import abc_to_alpha_beta
from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.simulate import simulate
from pmsmjax.units import rpm_to_rad_s

__all__ = ["LOG_COLUMNS", "drive_log", "add_measurement_noise", "speed_scenario"]

#: The columns of a stator-frame log, and the truth columns.
LOG_COLUMNS = ("time", "u_alpha", "u_beta", "i_alpha", "i_beta")
TRUTH_COLUMNS = ("theta_e", "omega_m")


def speed_scenario(
    speed_rpm: float, duration_s: float = 0.3, load_nm: float = 10.0, load_time_s: float = 0.15
) -> Scenario:
    """Speed step from rest to ``speed_rpm`` at t = 0, load step 0 -> ``load_nm`` at ``load_time_s``."""
    return Scenario(
        duration_s=duration_s,
        speed_ref=Profile.constant(rpm_to_rad_s(speed_rpm)),
        load_torque=Profile.step(load_time_s, 0.0, load_nm),
    )


def drive_log(
    drive: Drive, scenario: Scenario, *, noise: float = 0.0, seed: int = 0
) -> dict[str, np.ndarray]:
    """Simulate ``drive`` (its estimator in the loop, the exact sensor for the book drive) through
    ``scenario`` and return the log: ``(N,)`` float64 columns ``time, u_alpha, u_beta, i_alpha, i_beta,
    theta_e, omega_m`` with ``noise`` (relative, see the module docstring) on voltages and currents."""
    tr = simulate(drive, scenario)
    u = np.asarray(abc_to_alpha_beta(tr.u_abc), dtype=np.float64)
    i = np.asarray(abc_to_alpha_beta(tr.i_abc), dtype=np.float64)
    log = {
        "time": np.asarray(tr.t, dtype=np.float64),
        "u_alpha": u[:, 0],
        "u_beta": u[:, 1],
        "i_alpha": i[:, 0],
        "i_beta": i[:, 1],
        "theta_e": np.asarray(tr.theta_e, dtype=np.float64),
        "omega_m": np.asarray(tr.omega_m, dtype=np.float64),
    }
    return add_measurement_noise(log, noise, seed) if noise > 0 else log


def add_measurement_noise(log: dict[str, np.ndarray], level: float, seed: int = 0) -> dict[str, np.ndarray]:
    """A copy of ``log`` with white noise of ``level`` x RMS magnitude on ``u_alpha, u_beta`` and on
    ``i_alpha, i_beta`` (independent draws from ``seed``)."""
    rng = np.random.default_rng(seed)
    out = dict(log)
    for a, b in (("u_alpha", "u_beta"), ("i_alpha", "i_beta")):
        sigma = level * float(np.sqrt(np.mean(log[a] ** 2 + log[b] ** 2)))
        out[a] = log[a] + sigma * rng.standard_normal(log[a].shape)
        out[b] = log[b] + sigma * rng.standard_normal(log[b].shape)
    return out
