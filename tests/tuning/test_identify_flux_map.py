"""Flux-map identification (tuning/identify/flux_map_fit.py) on noisy logs of an analytic saturated machine
integrated by SciPy (tuning/identify/saturated_reference_log.py), checked against the analytic flux:

- the map's RMS error over the visited currents is within 1.5 % of the flux range and below the error of
  the true map sampled at the log's steady operating points and interpolated the same way (what a fit of
  the steady points alone could at best give), R within 2 %;
- with a bridge's voltage error in the log (dead time and device drop, a sign ramping over the PWM
  ripple, not the fit's tanh), that voltage within 10 % and R within 2.5 %;
- on a log of ordinary closed-loop operation (a speed loop from rest through speed reversals and load
  steps, the d current a fixed share of the q current: one path through the current plane), the map
  over the visited currents within 1.5 % of the flux range and R within 2 % at every grid step, the
  nodes off the path marked;
- the map is symmetric about the d axis (psi_d even, psi_q odd in i_q) unless told otherwise, and its MTPA
  locus a motor's on both torque signs where the same log fitted without the symmetry fails;
- careless logs are refused in one line; the measured marks survive the CSV.
"""

import numpy as np
import pytest

from pmsmjax.io.flux_map_files import read_flux_map, read_flux_map_measured, write_flux_map_csv
from pmsmjax.machines.flux_map import FluxMapGrid
from pmsmjax.spec.validation import ParameterError
from tuning.identify.flux_map_fit import fit_flux_map
from tuning.identify.log import drive_log_from_columns
from tuning.identify.saturated_reference_log import (
    SATURATED_IPM,
    bridge_error,
    flux_map_log,
    saturated_flux,
    speed_controlled_log,
)

OPS_D, OPS_Q = np.array([-8.0, -4.0, 0.0]), np.array([-8.0, -4.0, 0.0, 4.0, 8.0])
SPEED_RPM, DWELL_S = 1000.0, 4e-3


def _log(**kwargs):
    raw = flux_map_log(SATURATED_IPM, OPS_D, OPS_Q, speed_rpm=SPEED_RPM, dwell_s=DWELL_S, **kwargs)
    return drive_log_from_columns(raw, SATURATED_IPM["pole_pairs"], hold="stator")


def _visited(i_dq, cell=0.25):
    """Distinct visited currents on a 0.25 A raster: the region counted once per place, not per sample."""
    return np.unique(np.round(i_dq / cell).astype(int), axis=0) * cell


def _rms_error(grid, points):
    err = np.array([grid.at(*p)[0] for p in points]) - saturated_flux(SATURATED_IPM, *points.T)[0]
    return float(np.sqrt(np.mean(err**2)))


@pytest.fixture(scope="module")
def noisy_log():
    return _log(seed=3)


def test_analytic_machine_is_the_preset_map():
    grid = read_flux_map("pmsmjax/presets/motors/saturated_ipm_map.csv")
    D, Q = np.meshgrid(grid.i_d, grid.i_q, indexing="ij")
    psi, L = saturated_flux(SATURATED_IPM, D, Q)
    np.testing.assert_allclose(psi[..., 0], grid.psi_d, atol=1e-9)
    np.testing.assert_allclose(psi[..., 1], grid.psi_q, atol=1e-9)
    h = 1e-6  # the closed-form L_inc against central differences of the flux
    fd = (
        saturated_flux(SATURATED_IPM, 3.0 + h, -5.0)[0] - saturated_flux(SATURATED_IPM, 3.0 - h, -5.0)[0]
    ) / (2 * h)
    np.testing.assert_allclose(saturated_flux(SATURATED_IPM, 3.0, -5.0)[1][:, 0], fd, rtol=1e-7)


def test_map_beats_the_steady_points_and_R(noisy_log):
    fit = fit_flux_map(noisy_log, SATURATED_IPM["pole_pairs"], step_a=2.0)
    points = _visited(noisy_log.i_dq)
    psi_true = saturated_flux(SATURATED_IPM, *points.T)[0]
    flux_range = float(np.ptp(psi_true, axis=0).max())
    D, Q = np.meshgrid(OPS_D, OPS_Q, indexing="ij")
    steady = saturated_flux(SATURATED_IPM, D, Q)[0]
    steady_map = FluxMapGrid(OPS_D, OPS_Q, steady[..., 0], steady[..., 1])
    identified, sampled = _rms_error(fit.grid, points), _rms_error(steady_map, points)
    assert identified / flux_range < 0.0012  # measured 0.090 % (0.12 % without the symmetry); required 1.5 %
    assert identified < 0.35 * sampled  # measured 0.25x (0.34x without the symmetry)
    assert abs(fit.R / SATURATED_IPM["R"] - 1.0) < 0.008  # measured -0.49 %; the requirement is 2 %


def _motor_locus(grid) -> bool:
    """Whether ``grid``'s MTPA locus rises with the current up to the grid's corner current, both torque
    signs: the check a drive file with the map makes (pmsmjax.spec.design_rules)."""
    from pmsmjax.controllers.flux_map_loci import mtpa_table

    corner = max(np.hypot(d, q) for d in grid.i_d[[0, -1]] for q in grid.i_q[[0, -1]])
    try:
        mtpa_table(grid, SATURATED_IPM["pole_pairs"], corner)
    except ParameterError:
        return False
    return True


def test_the_map_is_symmetric_about_the_d_axis_and_its_locus_a_motors():
    """The flux-map notebook's staircase (seed 1) at 2 A: psi_d even and psi_q odd in i_q to rounding, at
    the nodes and between them, psi_q zero on i_q = 0, and the MTPA locus a motor's on both torque signs up
    to the grid's corner current; fitted without the symmetry, the same log's locus fails at the corner
    (outside the grid, on the edge's inductance)."""
    log = _log(seed=1)
    fit = fit_flux_map(log, SATURATED_IPM["pole_pairs"], step_a=2.0)
    grid = fit.grid
    assert fit.q_symmetric and np.array_equal(grid.i_q, -grid.i_q[::-1])
    np.testing.assert_allclose(grid.psi_d, grid.psi_d[:, ::-1], rtol=0, atol=1e-15)
    np.testing.assert_allclose(grid.psi_q, -grid.psi_q[:, ::-1], rtol=0, atol=1e-15)
    assert np.all(grid.psi_q[:, grid.i_q == 0.0] == 0.0)
    np.testing.assert_array_equal(fit.measured, fit.measured[:, ::-1])
    rng = np.random.default_rng(0)
    points = np.column_stack([rng.uniform(-12, 4, 50), rng.uniform(0, 10, 50)])  # inside and beyond
    up, down = grid.flux(points)[0], grid.flux(points * [1, -1])[0]
    np.testing.assert_allclose(down, up * [1, -1], rtol=0, atol=1e-12)
    assert _motor_locus(grid)
    D, Q = np.meshgrid(grid.i_d, grid.i_q, indexing="ij")
    truth = saturated_flux(SATURATED_IPM, D, Q)[0]
    error = np.hypot(grid.psi_d - truth[..., 0], grid.psi_q - truth[..., 1])[fit.measured]
    span = np.ptp(truth[fit.measured], axis=0).max()
    assert np.sqrt(np.mean(error**2)) / span < 0.003  # measured 0.21 % at 52 of 63 points
    points = _visited(log.i_dq)
    flux_range = float(np.ptp(saturated_flux(SATURATED_IPM, *points.T)[0], axis=0).max())
    assert _rms_error(grid, points) / flux_range < 0.0011  # measured 0.087 %
    free = fit_flux_map(log, SATURATED_IPM["pole_pairs"], step_a=2.0, q_symmetric=False)
    assert not free.q_symmetric and not np.allclose(free.grid.psi_d, free.grid.psi_d[:, ::-1], atol=1e-6)
    assert not _motor_locus(free.grid)  # measured: its locus jumps at 12.8 A
    assert _rms_error(free.grid, points) > _rms_error(grid, points)  # measured 0.114 % against 0.087 %


# Ordinary operation: speed steps through both directions of rotation (r/min) and load steps (N m).
SPEED_STEPS = [(0.0, 1000.0), (0.25, 400.0), (0.4, -1000.0), (0.7, -300.0)]
LOAD_STEPS = [(0.12, 3.0), (0.2, -2.0), (0.32, 4.0), (0.5, -3.0), (0.6, 2.0), (0.78, -4.0)]


@pytest.fixture(scope="module")
def closed_loop_log():
    raw = speed_controlled_log(
        SATURATED_IPM, SPEED_STEPS, LOAD_STEPS, duration_s=0.9, inertia_kgm2=0.002, friction_nms=0.001, seed=1
    )
    return drive_log_from_columns(raw, SATURATED_IPM["pole_pairs"], hold="stator")


def test_the_closed_loop_log_is_speed_controlled(closed_loop_log):
    # the speed loop turns the rotor each way the reference asks and follows it, under the load steps, to
    # within a quarter of the top speed before the next step (the log is ordinary operation, not a walk)
    speed_rpm = closed_loop_log.omega_m * 30.0 / np.pi
    for (t_step, reference), (t_next, _) in zip(SPEED_STEPS, [*SPEED_STEPS[1:], (0.9, None)], strict=True):
        settled = (closed_loop_log.time > t_next - 0.02) & (closed_loop_log.time < t_next)
        assert np.all(np.abs(speed_rpm[settled] - reference) < 250.0), t_step
        assert np.all(np.sign(speed_rpm[settled]) == np.sign(reference)), t_step
    i_d, i_q = closed_loop_log.i_dq.T
    assert np.ptp(i_q) > 20.0 and np.ptp(i_d) < 7.0  # a path, not a grid: i_d follows -0.4 |i_q|


@pytest.mark.parametrize("step_a", [None, 2.0, 4.0])
def test_a_log_of_ordinary_operation_gives_the_map_along_its_path(closed_loop_log, step_a):
    """Off the path the nodes are fixed only in combination; the energy-storing constraints keep the map
    usable there (active at 5 A, not at 2 A, the default step here, nor at 4 A)."""
    fit = fit_flux_map(closed_loop_log, SATURATED_IPM["pole_pairs"], step_a=step_a)
    points = _visited(closed_loop_log.i_dq)
    flux_range = float(np.ptp(saturated_flux(SATURATED_IPM, *points.T)[0], axis=0).max())
    assert _rms_error(fit.grid, points) / flux_range < 0.005  # measured 0.089-0.32 %; required 1.5 %
    assert abs(fit.R / SATURATED_IPM["R"] - 1.0) < 0.02  # measured within 0.17 %
    assert 0 < fit.measured.sum() < fit.measured.size  # the nodes off the path are marked


def test_cli_says_where_the_energy_constraints_hold_the_map(closed_loop_log, tmp_path, capsys):
    import json

    from pmsmjax.cli import main
    from pmsmjax.io.logs import write_csv_atomic

    log = closed_loop_log
    columns = {"time": log.time, "u_d": log.u_dq[:, 0], "u_q": log.u_dq[:, 1], "i_d": log.i_dq[:, 0]}
    columns |= {"i_q": log.i_dq[:, 1], "omega_m": log.omega_m, "theta_e": log.theta_e}
    write_csv_atomic(tmp_path / "log.csv", columns)
    out = tmp_path / "out"
    args = ["identify", str(tmp_path / "log.csv"), "--flux-map", "--pole-pairs", "4", "--out", str(out)]
    # a 5 A grid along the path: fitted freely, its map stores no energy at nodes off the path
    assert main(args + ["--flux-map-step", "5", "--fix", "J=0.002", "B=0.001"]) == 0
    said = capsys.readouterr().out
    constraints = json.loads((out / "flux_map.json").read_text())["energy_constraints"]
    assert constraints > 0 and f"{constraints} energy-storing constraints active" in said


def test_bridge_error_on_a_phase_axis():
    # current along phase a: a positive, b and c negative half as much; sharp sign: e_abc = u (1, -1, -1),
    # minus its common mode u/3 -> 4/3 u on phase a's axis (d at theta = 0), none across it
    np.testing.assert_allclose(bridge_error(np.array([5.0, 0.0]), 0.0, 3.0, 0.0), [4.0, 0.0], atol=1e-12)
    # inside the ramp (every |i_x| below the ripple) the error is a resistance u / ripple: 3 ohm x 0.2 A
    np.testing.assert_allclose(bridge_error(np.array([0.2, 0.0]), 0.0, 3.0, 1.0), [0.6, 0.0], atol=1e-12)


@pytest.mark.slow  # 15 s: a log of its own, a fit profiling the sign width and one at a fixed width
def test_inverter_error_voltage():
    # a bridge of 1 us dead time at 10 kHz and 311 V, 0.8 V drop, sign ramping over the PWM ripple: not the
    # fit's tanh model
    u_err = 1e-6 / 1e-4 * 311.0 + 0.8
    log = _log(seed=4, dead_time_s=1e-6, device_drop_v=0.8)
    fit = fit_flux_map(log, SATURATED_IPM["pole_pairs"], step_a=2.0, inverter_error=True)
    assert abs(fit.V_e / u_err - 1.0) < 0.03  # measured +1.4 %; the requirement is 10 %
    assert abs(fit.R / SATURATED_IPM["R"] - 1.0) < 0.025  # measured -1.7 %
    assert 0.3 < fit.error_smoothing_a < 0.8  # measured 0.53 A; the ripple's half amplitude is 0.71 A
    fixed = fit_flux_map(
        log, SATURATED_IPM["pole_pairs"], step_a=2.0, inverter_error=True, error_smoothing_a=0.1
    )
    assert abs(fixed.R / SATURATED_IPM["R"] - 1.0) > 0.08  # measured +11 %: why the width is fitted


def test_careless_logs_are_refused(noisy_log):
    import dataclasses

    one_way = dataclasses.replace(noisy_log, omega_m=np.abs(noisy_log.omega_m))
    with pytest.raises(ParameterError, match="one way only.*--fix R="):
        fit_flux_map(one_way, 4)
    still = dataclasses.replace(noisy_log, omega_m=np.zeros_like(noisy_log.omega_m))
    with pytest.raises(ParameterError, match="hardly turns"):
        fit_flux_map(still, 4, R=0.5)
    parked = dataclasses.replace(noisy_log, i_dq=np.zeros_like(noisy_log.i_dq) + 1e-3)
    with pytest.raises(ParameterError, match="visit no region"):
        fit_flux_map(parked, 4, step_a=2.0)
    swapped = dataclasses.replace(noisy_log, u_dq=noisy_log.u_dq[:, ::-1].copy())
    with pytest.raises(ParameterError, match="not a usable flux map.*column order and signs"):
        fit_flux_map(swapped, 4, step_a=2.0)


def test_cli_writes_a_drive_file_every_command_reads(noisy_log, tmp_path, capsys):
    import json

    from pmsmjax.cli import main
    from pmsmjax.io.drive_files import drive_spec
    from pmsmjax.io.logs import write_csv_atomic

    columns = {"time": noisy_log.time, "u_d": noisy_log.u_dq[:, 0], "u_q": noisy_log.u_dq[:, 1]}
    columns |= {"i_d": noisy_log.i_dq[:, 0], "i_q": noisy_log.i_dq[:, 1], "omega_m": noisy_log.omega_m}
    columns["theta_e"] = noisy_log.theta_e
    write_csv_atomic(tmp_path / "log.csv", columns)
    out = tmp_path / "out"
    args = ["identify", str(tmp_path / "log.csv"), "--flux-map", "--pole-pairs", "4", "--out", str(out)]
    assert main(args + ["--flux-map-step", "2", "--fix", "J=0.002", "B=0.001"]) == 0
    spec = drive_spec(str(out / "motor.toml"))
    assert abs(spec.motor["R"] / SATURATED_IPM["R"] - 1.0) < 0.008
    grid, marks = read_flux_map(out / "flux_map.csv"), read_flux_map_measured(out / "flux_map.csv")
    assert marks.shape == grid.psi_d.shape and 0 < marks.sum() < marks.size
    assert json.loads((out / "flux_map.json").read_text())["q_symmetric"] is True
    assert "symmetric about the d axis" in capsys.readouterr().out
    assert main(args + ["--fix", "L_q=0.003"]) != 0
    message = capsys.readouterr().err.strip().splitlines()
    assert len(message) == 1 and "--fix L_q=...: with --flux-map only R" in message[0]
    # the opt-out, for a rotor that is not symmetric about its d axis: every node fitted from the log
    assert main(args + ["--flux-map-step", "2", "--fix", "J=0.002", "B=0.001", "--no-q-symmetry"]) == 0
    assert json.loads((out / "flux_map.json").read_text())["q_symmetric"] is False
    free = read_flux_map(out / "flux_map.csv")
    assert not np.allclose(free.psi_q, -free.psi_q[:, ::-1], atol=1e-6)
    linear = [a for a in args if a != "--flux-map"]
    assert main(linear + ["--no-q-symmetry"]) != 0
    assert "--no-q-symmetry belongs to --flux-map" in capsys.readouterr().err


def test_measured_marks_round_trip(tmp_path):
    i_d, i_q = np.array([-2.0, 0.0, 2.0]), np.array([-1.0, 0.0, 1.0, 2.0])
    D, Q = np.meshgrid(i_d, i_q, indexing="ij")
    grid = FluxMapGrid(i_d, i_q, 0.1 + 3e-3 * D, 5e-3 * Q)
    marks = np.zeros(D.shape, dtype=bool)
    marks[1, 2] = marks[0, 3] = True
    path = write_flux_map_csv(tmp_path / "map.csv", grid, measured=marks)
    np.testing.assert_array_equal(read_flux_map_measured(path), marks)
    np.testing.assert_allclose(read_flux_map(path).psi_d, grid.psi_d)
    plain_path = write_flux_map_csv(tmp_path / "plain.csv", grid)
    assert read_flux_map_measured(plain_path) is None
    path.write_text(path.read_text().replace(",1\n", ",2\n", 1))
    with pytest.raises(ParameterError, match="measured column holds 2"):
        read_flux_map(path)


def test_cli_refuses_currents_in_mA_and_R_in_mohm_before_writing(noisy_log, tmp_path, capsys):
    from pmsmjax.cli import main
    from pmsmjax.io.logs import write_csv_atomic

    columns = {"time": noisy_log.time, "u_d": noisy_log.u_dq[:, 0], "u_q": noisy_log.u_dq[:, 1]}
    columns |= {"i_d": noisy_log.i_dq[:, 0] * 1e3, "i_q": noisy_log.i_dq[:, 1] * 1e3}
    columns |= {"omega_m": noisy_log.omega_m, "theta_e": noisy_log.theta_e}
    write_csv_atomic(tmp_path / "ma.csv", columns)
    out = tmp_path / "out"
    args = ["identify", str(tmp_path / "ma.csv"), "--flux-map", "--pole-pairs", "4", "--out", str(out)]
    assert main(args + ["--fix", "J=0.002", "B=0.001"]) != 0
    assert "in mA" in capsys.readouterr().err and not out.exists()
    columns |= {"i_d": noisy_log.i_dq[:, 0], "i_q": noisy_log.i_dq[:, 1]}
    write_csv_atomic(tmp_path / "ma.csv", columns)
    assert main(args + ["--fix", "R=500", "J=0.002", "B=0.001"]) != 0
    err = capsys.readouterr().err
    assert "R=500 ohm" in err and "R=0.5" in err and not out.exists()
