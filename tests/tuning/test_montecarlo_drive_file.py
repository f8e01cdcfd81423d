"""Monte Carlo studies of the user's drive (``pmsmjax montecarlo --motor FILE``): the book drive file
gives exactly the study of the book presets (drive, draws, thresholds, run length), a non-book drive file
gives its own drive, scenario, current limit and tolerances, and careless drive flags are refused before
anything compiles."""

import json

import jax
import numpy as np
import pytest

from pmsmjax import presets
from pmsmjax.cli import main
from pmsmjax.io.drive_files import drive_spec, preset_path
from pmsmjax.spec.validation import ParameterError
from tuning.montecarlo import study as mc_study
from tuning.montecarlo.distributions import Distribution, sample
from tuning.montecarlo.study import Study

#: The book study as it was written out before drive files: presets and constants, not the book file.
BOOK_SETTINGS = dict(current_bandwidth=1100.0, speed_bandwidth=50.0, current_limit=15.0, u_dc=311.0)
BOOK_TOLERANCES = {"motor.R": 0.2, "motor.L_d": 0.15, "motor.L_q": 0.15, "motor.psi_f": 0.1, "motor.J": 0.5,
                   "motor.B": 0.5, "bridge.u_dc": 0.1}  # fmt: skip


def _assert_same_tree(a, b):
    la, ta = jax.tree.flatten(a)
    lb, tb = jax.tree.flatten(b)
    assert ta == tb
    for x, y in zip(la, lb, strict=True):
        x, y = np.asarray(x), np.asarray(y)
        assert x.dtype == y.dtype and np.array_equal(x, y)


@pytest.mark.parametrize("estimator", [None, "smo"])
def test_the_book_drive_file_gives_the_book_study_bit_for_bit(estimator):
    study = Study(n=64, seed=3, estimator=estimator)  # --motor book, the default
    motor = presets.load_motor("book")
    old = presets.book_drive(motor, n_substeps=10, **BOOK_SETTINGS)
    if estimator:
        old = presets.with_observer(old, estimator, old.machine.motor, startup=True)
    drive = mc_study.build_drive(study)
    _assert_same_tree(drive, old)
    assert (study.speed_rpm, study.load_nm, study.load_time_s, study.duration_s) == (1000.0, 10.0, 0.2, 0.4)
    assert study.n_periods == 4000 and study.decimate == 40 and study.current_threshold == 1.05 * 15.0
    tolerances = BOOK_TOLERANCES if estimator is None else mc_study.SENSORLESS_TOLERANCES
    by_hand = {k: Distribution("uniform", float(mc_study._leaf(old, k)), v) for k, v in tolerances.items()}
    drawn = sample(mc_study.distributions(study, drive), 64, 3, "random")
    expected = sample(by_hand, 64, 3, "random")
    assert list(drawn) == list(expected)
    for k in expected:
        np.testing.assert_array_equal(drawn[k], expected[k])


def test_a_drive_file_gives_the_study_its_drive_scenario_limit_and_tolerances(tmp_path):
    spec = drive_spec("servo-400w")
    study = Study(motor="servo-400w", n=16)
    drive = mc_study.build_drive(study)
    assert float(drive.Ts) == pytest.approx(1.0 / 20000.0) and float(drive.bridge.u_dc) == 48.0
    assert float(drive.machine.motor.psi_f) == spec.motor["psi_f"]
    assert study.current_threshold == pytest.approx(1.05 * 36.0)
    assert study.duration_s == spec.scenario["duration_s"] and study.speed_rpm == spec.scenario["speed_rpm"]
    assert study.n_periods == round(spec.scenario["duration_s"] * 20000.0)
    assert study.parameters == {
        mc_study.TOLERANCE_PARAMETERS[k]: {"distribution": "uniform", "tolerance": v}
        for k, v in spec.tolerances.items()
    }
    # The study's own [parameters] still win; --u-dc overrides the file's DC link.
    own = Study(motor="servo-400w", u_dc=60.0, parameters={"motor.R": {"tolerance": 0.01}})
    assert own.u_dc == 60.0 and own.spec.u_dc_v == 60.0 and list(own.parameters) == ["motor.R"]


@pytest.mark.slow
def test_command_on_a_non_book_drive_writes_its_summary_and_draws_within_its_tolerances(tmp_path, capsys):
    config = tmp_path / "study.toml"
    config.write_text("[study]\nsensitivity_runs = 0\n[scenario]\nduration_s = 0.02\nload_time_s = 0.01\n")
    out = tmp_path / "mc"
    argv = ["montecarlo", "--motor", "servo-400w", "--n", "16", "--config", str(config), "--out", str(out),
            "--no-figures", "--no-progress"]  # fmt: skip
    assert main(argv) == 0
    summary = json.loads((out / "summary.json").read_text())
    spec = drive_spec("servo-400w")
    assert summary["drive_file"]["source"] == "servo-400w"
    assert (
        summary["drive_file"]["motor"] == spec.motor
        and summary["drive_file"]["tolerances"] == spec.tolerances
    )
    assert summary["study"]["current_limit"] == 36.0 and summary["study"]["u_dc"] == 48.0
    assert summary["study"]["duration_s"] == 0.02 and summary["study"]["speed_rpm"] == 3000.0
    assert summary["n_runs"] == 16
    study = Study(**{**summary["study"], "parameters": None})
    dists = mc_study.distributions(study, mc_study.build_drive(study))
    for name, x in sample(dists, 16, study.seed, study.sampling).items():
        d = summary["parameters"][name]
        key = name.split(".", 1)[1].replace("u_dc", "u_dc_v")
        assert d["tolerance"] == spec.tolerances[key]
        nominal = spec.u_dc_v if name == "bridge.u_dc" else spec.motor[key]
        assert d["nominal"] == pytest.approx(nominal, rel=1e-6)
        assert np.all(np.abs(x / nominal - 1.0) <= d["tolerance"] + 1e-12), name
    assert "servo-400w" in capsys.readouterr().out


@pytest.mark.parametrize(
    "flags, needles",
    [
        (["--motor", "nosuch"], ["--motor nosuch", "neither a preset"]),
        (["--u-dc", "0.048"], ["--u-dc", "0.048 V", "outside"]),
        (["--motor", "book", "--current-limit", "5"], ["--current-limit", "5 A", "below"]),
        (["--machine", "six-phase", "--motor", "servo-400w"], ["--motor servo-400w", "neither a preset"]),
    ],
)
def test_careless_drive_flags_are_refused_before_anything_is_written(tmp_path, capsys, flags, needles):
    out = tmp_path / "mc"
    assert main(["montecarlo", "--n", "4", "--out", str(out), *flags]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and not out.exists()
    for needle in needles:
        assert needle in err


def test_a_six_phase_drive_file_gives_the_six_phase_study_its_motor_and_tolerances(tmp_path):
    path = tmp_path / "six.toml"
    path.write_text(
        preset_path("book", 6).read_text().replace("R = 0.479", "R = 0.61").replace("J = 0.5", "J = 0.25")
    )
    study = Study(motor=str(path), machine="six-phase")
    drive = mc_study.build_drive(study)
    assert float(drive.machine.motor.R) == 0.61 and drive.machine.motor.n_phases == 6
    assert (
        study.parameters["motor.J"]["tolerance"] == 0.25 and study.parameters["motor.R"]["tolerance"] == 0.2
    )
    with pytest.raises(ParameterError, match="six-phase motor"):
        Study(motor=str(path))  # a six-phase file on the three-phase study


@pytest.mark.slow
def test_a_sensorless_study_on_a_flux_map_file_runs_the_map_aware_observer(tmp_path):
    """On a drive file with a flux map the study's observer reads the map (as demo and compare run it), and
    its figures count from the end of the file's own I/f hand-over: saturated-ipm with the flux observer
    holds the angle within 2 electrical degrees on every draw (the constant-model observer: 16.7 degrees RMS,
    the map's steady angle error)."""
    from pmsmjax.estimators.map_flux_observer import MapFluxObserver
    from pmsmjax.jobs.estimator_comparison import handover_settled_s

    study = Study(motor="saturated-ipm", n=8, estimator="flux-observer")
    drive = mc_study.build_drive(study)
    assert isinstance(drive.estimator.observer, MapFluxObserver)
    assert drive.estimator.observer.flux_map is not None
    assert handover_settled_s(drive) > 0.08  # its start-up lasts longer than the book's
    out = tmp_path / "mc"
    assert main(["montecarlo", "--motor", "saturated-ipm", "--estimator", "flux-observer", "--n", "8",
                 "--no-progress", "--no-figures", "--out", str(out)]) == 0  # fmt: skip
    metrics = json.loads((out / "summary.json").read_text())["metrics"]
    assert metrics["angle_error_max_deg"]["max"] < 2.0
