"""The drive-rating rules (pmsmjax/spec/design_rules.py) on a drive file with a flux map, against the
analytic model the preset saturated-ipm map was sampled from: the rated torque is the most torque of the
rated current (dense angle search), the base speed the speed where the least-current point of the rated
torque needs 95 % of the voltage limit (scipy: brentq for the magnitude at each angle, minimised over
the angle; brentq for the speed). The linear model the map derives (L_d > L_q at the rated current:
reverse saliency) would give other figures; both are checked to differ.
"""

import math

import numpy as np
import pytest
from controllers.test_flux_map_references import psi_preset, torque_preset
from scipy.optimize import brentq, minimize_scalar

from pmsmjax.io.drive_files import drive_spec
from pmsmjax.spec import design_rules as rules

RPM = math.pi / 30.0


@pytest.fixture(scope="module")
def spec():
    return drive_spec("saturated-ipm")


def analytic_most_torque(current):
    beta = np.linspace(0.0, np.pi, 200001)
    return float(np.max(torque_preset(current * np.cos(beta), current * np.sin(beta))))


def analytic_least_current_point(torque):
    """``(i_d, i_q)`` of least |i| with the analytic torque ``torque``: for each current angle the magnitude
    giving that torque (brentq), minimised over the angle (bounded Brent; a dense scan brackets it)."""

    def magnitude(beta):
        f = lambda current: torque_preset(current * np.cos(beta), current * np.sin(beta)) - torque
        return brentq(f, 1e-9, 200.0, xtol=1e-13)

    betas = np.linspace(np.pi / 2 - 0.6, np.pi / 2 + 0.6, 241)
    k = int(np.argmin([magnitude(b) for b in betas]))
    result = minimize_scalar(
        magnitude, bounds=(betas[k - 1], betas[k + 1]), method="bounded", options={"xatol": 1e-12}
    )
    beta, current = result.x, magnitude(result.x)
    return np.array([current * np.cos(beta), current * np.sin(beta)])


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
