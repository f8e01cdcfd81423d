"""The margins in the tuning objective and the Monte Carlo stability check, against the linearisation
called directly on each drive: `margin_penalty` is the shortfall of the worst loop computed by hand from
`loop_margins`, and `spectral_radii` the eigenvalues of each draw's own `linearise` (NumPy), an unstable
current-loop gain flagged (spectral radius above 1) where the design-rule gains are stable."""

import dataclasses
import types

import jax.numpy as jnp
import numpy as np
import pytest

from pmsmjax.analysis.loop_linearisation import LOOPS, linearise
from pmsmjax.analysis.margins import loop_margins
from tuning.autotune.margin_constraints import margin_penalty
from tuning.autotune.objectives import ObjectiveWeights
from tuning.montecarlo import study as mc_study
from tuning.montecarlo.linear_stability import spectral_radii

SPEED_RAD_S, LOAD_NM = 90.0, 5.0


@pytest.fixture(scope="module")
def book():
    return mc_study.build_drive(mc_study.Study(n=2))


def test_margin_penalty_is_the_worst_loops_shortfall(book):
    lin = linearise(book, SPEED_RAD_S, LOAD_NM)
    pm = {loop: float(loop_margins(lin, loop).phase_margin_deg) for loop in LOOPS}
    ms = {loop: float(loop_margins(lin, loop).sensitivity_peak) for loop in LOOPS}
    nominal = types.SimpleNamespace(plant_scale={})  # one plant: the drive itself
    same = lambda drive, scale: drive  # noqa: E731
    base = ObjectiveWeights(margin_speed_rad_s=SPEED_RAD_S, margin_load_nm=LOAD_NM, margin_penalty=0.1)

    # floors both loops meet: no penalty
    met = dataclasses.replace(base, min_phase_margin_deg=min(pm.values()) - 5.0, max_sensitivity_peak=3.0)
    assert float(margin_penalty(book, nominal, met, same)) == 0.0
    # a phase-margin floor above both loops: the sum of each loop's shortfall (the worst plant of one)
    floor = max(pm.values()) + 4.0
    weights = dataclasses.replace(base, min_phase_margin_deg=floor)
    expected = 0.1 * sum(floor - p for p in pm.values())
    assert float(margin_penalty(book, nominal, weights, same)) == pytest.approx(expected, rel=1e-4)
    # a sensitivity ceiling below both peaks: per 0.01 above it
    ceiling = min(ms.values()) - 0.02
    weights = dataclasses.replace(base, max_sensitivity_peak=ceiling)
    expected = 0.1 * 100.0 * sum(m - ceiling for m in ms.values())
    assert float(margin_penalty(book, nominal, weights, same)) == pytest.approx(expected, rel=1e-4)


def test_spectral_radii_are_each_draws_eigenvalues(book):
    study = mc_study.Study(n=3, speed_rpm=SPEED_RAD_S * 30.0 / np.pi, load_nm=LOAD_NM)
    names = ("motor.R", "controller.current.kp_q", "controller.current.kp_d")
    kp = float(book.controller.current.kp_q)
    # the design rule, a 20 % warmer winding, and the current gains 40x: beyond the delayed loop's limit
    values = np.array([[float(book.machine.motor.R), kp, kp],
                       [1.2 * float(book.machine.motor.R), kp, kp],
                       [float(book.machine.motor.R), 40.0 * kp, 40.0 * kp]])  # fmt: skip
    radii, seconds = spectral_radii(book, study, names, values, mc_study.apply_sample, chunk=2)
    assert seconds > 0.0
    for row, radius in zip(values, radii, strict=True):
        drive, scenario = mc_study.apply_sample(book, study, names, jnp.asarray(row))
        lin = linearise(drive, scenario.speed_ref.values[-1], scenario.load_torque.values[-1], check=False)
        by_hand = np.max(np.abs(np.linalg.eigvals(np.asarray(lin.A, dtype=np.float64))))
        assert radius == pytest.approx(by_hand, rel=1e-6)
    assert radii[0] < 1.0 and radii[1] < 1.0 and radii[2] > 1.0, radii


def test_linear_stability_out_of_scope_is_refused_before_anything_runs(tmp_path, capsys):
    from pmsmjax.cli import main

    out = tmp_path / "mc"
    argv = [
        "montecarlo",
        "--u-dc",
        "150",
        "--linear-stability",
        "--n",
        "4",
        "--no-progress",
        "--out",
        str(out),
    ]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "needs" in err[0] and "voltage limit" in err[0]
    assert not out.exists()
