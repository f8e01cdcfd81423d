"""Flux-map identification on a PM-assisted synchronous reluctance machine (tuning/identify/
reluctance_reference_log.py: the power-law current map with strong self- and cross-saturation, the q-axis
incremental inductance falling from 57 to 6 mH over the staircase, integrated by SciPy with the flux as the
state), at the fit's default settings:

- a 35-point staircase at 400 r/min one way, 40 ms a point, noise 0.05 A and 0.5 V, R given, through
  ``pmsmjax identify --flux-map``: the map's RMS error over the visited currents below that of the
  steady-state estimate at the staircase points (interpolated the same way), and below it on the
  transients' paths, where only the transients inform; the log motors only (i_q >= 0), and with the
  d-axis symmetry the generating half is the motoring half's mirror image, so ``motor.toml`` is written
  (its MTPA locus a motor's on both torque signs);
- a log of ordinary operation (speed steps through both directions, load steps, the d current a fixed
  share of the q current): the map along its path.
"""

import numpy as np
import pytest

from tuning.identify.flux_map_fit import fit_flux_map
from tuning.identify.log import drive_log_from_columns
from tuning.identify.reluctance_reference_log import (
    STAIRCASE_D,
    STAIRCASE_Q,
    SYRM,
    steady_state_map,
    syrm_flux,
    syrm_speed_controlled_log,
    syrm_staircase_log,
)

P = SYRM["pole_pairs"]


def _errors(grid, i_dq):
    """``(all, near dwells, on the paths between)``: RMS flux error, as shares of the flux range, over the
    visited currents (each 0.25 A cell counted once), over those within 0.5 A of an operating point, and
    over the others."""
    points = np.unique(np.round(i_dq / 0.25).astype(int), axis=0) * 0.25
    true = syrm_flux(SYRM, *points.T)[0]
    flux_range = float(np.ptp(true, axis=0).max())
    err = np.sum((grid.flux(points)[0] - true) ** 2, axis=1) / 2.0
    D, Q = np.meshgrid(STAIRCASE_D, STAIRCASE_Q, indexing="ij")
    dwells = np.stack([D.ravel(), Q.ravel()], -1)
    near = np.min(np.linalg.norm(points[:, None] - dwells[None], axis=-1), axis=1) < 0.5
    return tuple(float(np.sqrt(np.mean(e))) / flux_range for e in (err, err[near], err[~near]))


def test_the_machine_saturates_tenfold_and_stores_energy():
    psi, L = syrm_flux(SYRM, np.array([0.0, 0.0, -16.0]), np.array([0.0, 24.0, 24.0]))
    assert L[0, 1, 1] / L[1, 1, 1] > 9.0  # 57.5 / 6.17 mH along q
    assert np.all(np.linalg.eigvalsh(L) > 0) and np.allclose(L, np.swapaxes(L, 1, 2))
    assert psi[0, 0] == pytest.approx(SYRM["psi_pm"]) and psi[0, 1] == 0.0  # the magnet along d


@pytest.mark.slow  # 15 s: 1.4 s of log at 10 kHz integrated by DOP853, and the fit
def test_staircase_map_beats_the_steady_state_estimate_and_writes_motor_toml(tmp_path, capsys):
    from pmsmjax.cli import main
    from pmsmjax.io.drive_files import drive_spec
    from pmsmjax.io.flux_map_files import read_flux_map
    from pmsmjax.io.logs import write_csv_atomic

    raw = syrm_staircase_log(seed=1)
    log = drive_log_from_columns(raw, P, hold="stator")
    assert log.i_dq[:, 1].min() > -1.0  # motoring only: the generating half-plane is never visited
    write_csv_atomic(tmp_path / "log.csv", raw)
    out = tmp_path / "out"
    args = ["identify", str(tmp_path / "log.csv"), "--flux-map", "--pole-pairs", str(P), "--out", str(out)]
    assert main(args + ["--fix", f"R={SYRM['R']}", "J=0.015", "B=0.005", "--no-figures"]) == 0
    spec = drive_spec(str(out / "motor.toml"))  # the drive file's MTPA check passed, both torque signs
    assert spec.motor["pole_pairs"] == P and "wrote" in capsys.readouterr().out
    grid = read_flux_map(out / "flux_map.csv")
    identified = _errors(grid, log.i_dq)
    steady = _errors(steady_state_map(log, SYRM["R"], P), log.i_dq)
    assert grid.step[0] == 2.5  # the default step the sample density gives
    assert np.array_equal(grid.i_q, -grid.i_q[::-1])  # the half grid's mirror image: i_q -25 to 25 A
    assert identified[0] < 0.6 * steady[0]  # measured 0.078 % against 0.167 %
    assert identified[2] < 0.6 * steady[2]  # on the transients' paths
    assert identified[1] < 0.001  # at the dwells, where the steady-state estimate is at its best


@pytest.mark.slow  # 20 s: 1 s of log, and the fit
def test_a_log_of_ordinary_operation():
    speed = [(0.0, 600.0), (0.3, 250.0), (0.5, -600.0), (0.8, -300.0)]
    load = [(0.15, 6.0), (0.25, -4.0), (0.4, 8.0), (0.62, -6.0), (0.72, 4.0), (0.9, -8.0)]
    raw = syrm_speed_controlled_log(
        SYRM, speed, load, duration_s=1.0, inertia_kgm2=0.015, friction_nms=0.005, seed=2
    )
    log = drive_log_from_columns(raw, P, hold="stator")
    fit = fit_flux_map(log, P, R=SYRM["R"])
    assert _errors(fit.grid, log.i_dq)[0] < 0.002  # measured 0.071 % (0.077 % without the symmetry)
    assert 0 < fit.measured.sum() < fit.measured.size  # a path: the nodes off it are marked
