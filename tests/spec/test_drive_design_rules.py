"""The rules of pmsmjax.spec.design_rules against independent calculations: MTPA by brute force over
the current angle, the base speed by solving the steady-state voltage equation with scipy, the delay
phase margin of the current-loop rule, the linear speed step of the speed-loop rule, the lcm period."""

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from pmsmjax.presets.book_constants import BOOK_MOTOR, BOOK_SALIENT_MOTOR
from pmsmjax.spec.design_rules import (
    base_speed_rpm,
    common_period_s,
    current_bandwidth_rule,
    current_for_torque,
    mtpa_d_current,
    round_up_nice,
    speed_bandwidth_rule,
    torque_at_current,
    voltage_limit_v,
    whole_period_speed_rpm,
)

SALIENT = dict(BOOK_SALIENT_MOTOR)
INDUSTRIAL = dict(R=0.63, L_d=0.018, L_q=0.025, psi_f=0.444, pole_pairs=2, J=0.05, B=0.005)


def _torque(m, i_d, i_q):
    return 1.5 * m["pole_pairs"] * i_q * (m["psi_f"] + (m["L_d"] - m["L_q"]) * i_d)


@pytest.mark.parametrize("motor", [dict(BOOK_MOTOR), SALIENT, INDUSTRIAL])
@pytest.mark.parametrize("current", [1.0, 10.0, 35.0])
def test_mtpa_is_the_most_torque_over_the_current_angle(motor, current):
    gamma = np.linspace(0.0, np.pi / 2, 200_001)  # i_d = -I sin, i_q = I cos
    best = np.max(_torque(motor, -current * np.sin(gamma), current * np.cos(gamma)))
    assert torque_at_current(motor, current) == pytest.approx(best, rel=1e-9)
    assert mtpa_d_current(motor, current) <= 0.0
    assert current_for_torque(motor, torque_at_current(motor, current)) == pytest.approx(current, rel=1e-9)


def test_base_speed_solves_the_voltage_equation():
    m, torque, u_lim = INDUSTRIAL, 30.5, voltage_limit_v(540.0)
    i_s = current_for_torque(m, torque + 0.0)
    i_d = mtpa_d_current(m, i_s)

    def voltage(speed_rpm):  # steady state, friction included: the MTPA current of T_L + B w
        w = speed_rpm * math.pi / 30
        current = current_for_torque(m, torque + m["B"] * w)
        i_d = mtpa_d_current(m, current)
        i_q = math.sqrt(current**2 - i_d**2)
        w_e = m["pole_pairs"] * w
        return math.hypot(
            m["R"] * i_d - w_e * m["L_q"] * i_q, m["R"] * i_q + w_e * (m["L_d"] * i_d + m["psi_f"])
        )

    expected = brentq(lambda n: voltage(n) - 0.95 * u_lim, 1.0, 10_000.0, xtol=1e-9)
    assert base_speed_rpm(m, torque, u_lim) == pytest.approx(expected, rel=1e-6)
    assert i_d < 0  # a salient motor's MTPA weakens the flux


def test_current_rule_keeps_its_phase_margin_against_the_delay():
    for Ts in (1e-4, 5e-5, 2e-4):
        a_c = current_bandwidth_rule(Ts)
        # loop a_c/s e^(-1.5 Ts s): crossover at a_c, phase -90 deg - 1.5 Ts a_c
        assert 90.0 - math.degrees(1.5 * Ts * a_c) == pytest.approx(65.0, abs=1e-9)
    assert current_bandwidth_rule(1e-4, phase_margin_deg=0.0) == pytest.approx(math.pi / 2 / 1.5e-4)


def test_speed_rule_keeps_a_fifth_of_rated_speed_linear():
    m = dict(BOOK_MOTOR)
    beta = speed_bandwidth_rule(m, 1e6, 15.0, 1000.0)  # current loop far faster: the linear bound rules
    k_t = 1.5 * m["pole_pairs"] * m["psi_f"]
    # the P part of the active-damping PI on a step of 200 r/min: beta J w / k_t, exactly the limit
    assert beta * m["J"] * 200 * math.pi / 30 / k_t == pytest.approx(15.0, rel=1e-12)
    assert speed_bandwidth_rule(m, 1100.0, 15.0, 1000.0) == pytest.approx(110.0)  # capped at a_c / 10


def test_whole_period_speed_and_common_period():
    assert common_period_s((62.5e-6, 10e-6, 25e-6)) == pytest.approx(250e-6)
    for speed, p, Ts in ((600.0, 14, 250e-6), (1750.0, 2, 200e-6), (1000.0, 4, 1e-4)):
        fit = whole_period_speed_rpm(speed, p, Ts)
        periods = 2 * 60 / (fit * p * Ts)
        assert fit <= speed and abs(periods - round(periods)) < 1e-9
        assert whole_period_speed_rpm(fit, p, Ts) == fit
    assert whole_period_speed_rpm(1000.0, 4, 1e-4) == 1000.0  # the book's speed fits as it is


def test_round_up_nice():
    assert [round_up_nice(x) for x in (0.198, 0.2, 0.21, 0.72, 3e-3, 0.0051)] == [
        0.2,
        0.2,
        0.25,
        1.0,
        0.005,
        0.01,
    ]
