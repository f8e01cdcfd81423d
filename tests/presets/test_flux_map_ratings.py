"""The drive-rating rules (pmsmjax/presets/drive_ratings.py) on a drive file with a flux map, against the
analytic model the preset saturated-ipm map was sampled from: the rated torque is the most torque of the
rated current (dense angle search), the base speed the speed where the least-current point of the rated
torque needs 95 % of the voltage limit (scipy: a constrained minimisation for the point, brentq for the
speed). The linear model the map derives (L_d > L_q at the rated current: reverse saliency) would give
other figures; both are checked to differ.
"""

import math

import numpy as np
import pytest
from controllers.test_flux_map_references import POLE_PAIRS, psi_preset, torque_preset
from scipy.optimize import brentq, minimize

from pmsmjax.io.drive_files import drive_spec
from pmsmjax.presets import drive_ratings as rules

RPM = math.pi / 30.0


@pytest.fixture(scope="module")
def spec():
    return drive_spec("saturated-ipm")


def analytic_most_torque(current):
    beta = np.linspace(0.0, np.pi, 200001)
    return float(np.max(torque_preset(current * np.cos(beta), current * np.sin(beta))))


def analytic_least_current_point(torque):
    """``(i_d, i_q)`` of least |i| with the analytic torque ``torque`` (SLSQP from the q axis)."""
    result = minimize(
        lambda x: x @ x,
        np.array([0.0, torque / (1.5 * POLE_PAIRS * 0.1)]),
        constraints=[{"type": "eq", "fun": lambda x: torque_preset(x[0], x[1]) - torque}],
        method="SLSQP",
        options={"ftol": 1e-14, "maxiter": 200},
    )
    assert result.success
    return result.x


def test_rated_torque_is_the_maps_mtpa_torque(spec):
    want = analytic_most_torque(spec.ratings["rated_current_a"])
    assert spec.ratings["rated_torque_nm"] == pytest.approx(want, rel=1e-5)  # measured 1e-7
    linear = {k: v for k, v in spec.motor.items() if k != "flux_map"}
    assert abs(rules.torque_at_current(linear, spec.ratings["rated_current_a"]) / want - 1.0) > 0.01


def test_base_speed_from_the_map(spec):
    m = spec.motor
    torque = spec.ratings["rated_torque_nm"]
    u_limit = rules.voltage_limit_v(spec.u_dc_v)

    def voltage_margin(speed_rpm):
        w = speed_rpm * RPM
        i_d, i_q = analytic_least_current_point(torque + m["B"] * w)
        psi_d, psi_q = psi_preset(i_d, i_q)
        w_e = m["pole_pairs"] * w
        return math.hypot(m["R"] * i_d - w_e * psi_q, m["R"] * i_q + w_e * psi_d) - 0.95 * u_limit

    want = brentq(voltage_margin, 100.0, 20000.0, xtol=1e-6)
    got = rules.base_speed_rpm(m, torque, u_limit)
    assert got == pytest.approx(want, rel=2e-4)
    linear = {k: v for k, v in m.items() if k != "flux_map"}
    assert abs(rules.base_speed_rpm(linear, torque, u_limit) / want - 1.0) > 0.01
