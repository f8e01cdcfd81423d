"""Steady operating points judged on a flux map: against the linear model's closed forms on a linear map, and
against SciPy's constrained optimiser on the PM-assisted reluctance machine's map."""

import math

import numpy as np
import pytest
from scipy.optimize import minimize

from pmsmjax.assemble import spec_drive
from pmsmjax.io.drive_files import drive_spec
from pmsmjax.machines.flux_map import FluxMapGrid
from pmsmjax.spec.map_steady_state import MapSteadyState, map_reachable, map_steady_state, map_top_speed_rpm
from pmsmjax.spec.steady_state import field_weakening_top_speed_rpm, reachable, top_speed_rpm

RPM = math.pi / 30.0


def linear_map(psi_f, L_d, L_q, span=60.0, n=25):
    axis = np.linspace(-span, span, n)
    D, Q = np.meshgrid(axis, axis, indexing="ij")
    return FluxMapGrid(axis, axis, L_d * D + psi_f, L_q * Q)


def test_linear_map_agrees_with_the_linear_model():
    """On a map of a linear salient machine, the map's verdicts are the linear model's closed forms: the top
    speed with i_d = 0 (surface machine) and with field weakening, to the polar grid's resolution."""
    motor = {"psi_f": 0.12, "L_d": 4e-3, "L_q": 4e-3, "R": 0.5, "pole_pairs": 4, "B": 0.0}
    steady = MapSteadyState(linear_map(0.12, 4e-3, 4e-3), 4, 0.5, 0.0, 20.0)
    u_limit, load = 180.0, 3.0
    top_mtpa = map_top_speed_rpm(steady, u_limit, load, field_weakening=False)
    assert top_mtpa == pytest.approx(top_speed_rpm(motor, u_limit, load), rel=5e-3)
    top_fw = map_top_speed_rpm(steady, u_limit, load, field_weakening=True)
    assert top_fw == pytest.approx(field_weakening_top_speed_rpm(motor, u_limit, 20.0, load), rel=1e-2)
    for speed in (0.5 * top_fw, 0.99 * top_fw, 1.02 * top_fw):
        ours = map_reachable(steady, speed, load, u_limit, True)
        theirs = reachable(motor, speed, load, u_limit, 20.0, True)
        assert ours["ok"] == theirs["ok"]
        assert ours["voltage"] == pytest.approx(theirs["voltage"], rel=1e-2)


def test_reluctance_machine_point_against_a_constrained_optimiser():
    """pm-syrm at 1.5x its rated speed with its rated load and a 40 A limit: the least steady voltage over
    currents in the limit that give the torque, by the grid search and by SLSQP on the same interpolant."""
    spec = drive_spec("pm-syrm")
    drive = spec_drive(spec, "pi")
    steady = map_steady_state(drive)
    assert steady is not None and map_steady_state(spec_drive(drive_spec("book"), "pi")) is None
    steady = MapSteadyState(steady.grid, steady.pole_pairs, steady.R, steady.B, 40.0)
    speed, load = 4500.0, 22.4
    pt = steady.point(speed, load, field_weakening=True)
    w_e = steady.pole_pairs * speed * RPM
    need = load + steady.B * speed * RPM

    def volts(i):
        psi_d, psi_q = steady.flux(i[0], i[1])
        return math.hypot(steady.R * i[0] - w_e * psi_q, steady.R * i[1] + w_e * psi_d)

    def torque(i):
        psi_d, psi_q = steady.flux(i[0], i[1])
        return 1.5 * steady.pole_pairs * (psi_d * i[1] - psi_q * i[0])

    best = min(
        (
            minimize(
                volts,
                x0,
                method="SLSQP",
                constraints=[
                    {"type": "ineq", "fun": lambda i: torque(i) - need},
                    {"type": "ineq", "fun": lambda i: 40.0**2 - i[0] ** 2 - i[1] ** 2},
                ],
            )
            for x0 in ([-30.0, 20.0], [-20.0, 30.0], [-35.0, 15.0])
        ),
        key=lambda r: r.fun if r.success else math.inf,
    )
    assert best.success
    assert pt["voltage"] == pytest.approx(best.fun, rel=0.02)
    assert (
        pt["voltage"] <= 0.95 * 540.0 / math.sqrt(3.0) * 0.97
    )  # fits the drive's voltage with field weakening
    assert map_reachable(steady, speed, load, 0.95 * 540.0 / math.sqrt(3.0), True)["ok"]


def test_pm_syrm_linear_model_would_misjudge_it():
    """Why the map is needed: the linear model derived from pm-syrm's map (its L_d, L_q, psi_f) calls the
    same point unreachable at any split of the current."""
    drive = spec_drive(drive_spec("pm-syrm"), "pi")
    m = drive.machine.motor
    linear = {
        "psi_f": float(m.psi_f), "L_d": float(m.L_d), "L_q": float(m.L_q), "R": float(m.R),
        "pole_pairs": int(m.pole_pairs), "B": float(m.B),
    }  # fmt: skip
    assert not reachable(linear, 4500.0, 22.4, 0.95 * 540.0 / math.sqrt(3.0), 40.0, True)["ok"]
