"""Monte Carlo draws of the current sensors: a drive file's ``[tolerances] current_offset_a`` (A, absolute)
and ``current_gain`` (relative) spread each sensor independently, and the runs see the drawn sensors."""

import numpy as np
import pytest

from pmsmjax.spec.validation import ParameterError
from tuning.montecarlo import study as mc_study
from tuning.montecarlo.distributions import Distribution, sample
from tuning.montecarlo.runner import run_study
from tuning.montecarlo.study import Study

DRIVE = """[motor]
R = 0.958
L_d = 0.00525
L_q = 0.00525
psi_f = 0.1827
pole_pairs = 4
J = 0.003
B = 0.008
[ratings]
rated_speed_rpm = 1000.0
rated_torque_nm = 10.0
max_current_a = 15.0
[sensor]
current_offset_a = [0.11, -0.07]
current_gain = [1.0, 1.018]
[tolerances]
R = 0.1
current_offset_a = 0.05
current_gain = 0.01
"""


def test_sensor_tolerances_are_drawn_per_sensor_and_reach_the_runs(tmp_path):
    path = tmp_path / "drive.toml"
    path.write_text(DRIVE)
    study = Study(motor=str(path), n=8, duration_s=0.02, load_time_s=0.01, sensitivity_runs=0, chunk_size=8)
    names = [f"current_sensor.{leaf}[{k}]" for leaf in ("offset_a", "gain") for k in range(2)]
    assert list(study.parameters) == ["motor.R", *names]
    drive = mc_study.build_drive(study)
    dists = mc_study.distributions(study, drive)
    drawn = sample(dists, study.n, study.seed)
    for k, nominal in enumerate([0.11, -0.07]):
        x = drawn[f"current_sensor.offset_a[{k}]"]
        assert np.all(np.abs(x - nominal) <= 0.05 + 1e-12) and np.ptp(x) > 0.02  # +-50 mA, not +-5 %
    for k, nominal in enumerate([1.0, 1.018]):
        assert np.all(np.abs(drawn[f"current_sensor.gain[{k}]"] / nominal - 1.0) <= 0.01 + 1e-12)
    values = np.asarray([drawn[n][3] for n in study.parameters])
    run_drive, _ = mc_study.apply_sample(drive, study, tuple(study.parameters), values)
    np.testing.assert_allclose(run_drive.current_sensor.offset_a, values[1:3], rtol=1e-6)
    summary = run_study(study, tmp_path / "mc", progress=False, figures=False)
    assert summary["n_runs"] == 8
    assert summary["parameters"]["current_sensor.offset_a[0]"]["absolute"] is True
    with pytest.raises(ParameterError, match="lognormal spread is for positive parameters"):
        Distribution("lognormal", 0.0, 0.05, absolute=True).check("current_sensor.offset_a[0]")


def test_robust_tuning_batches_draw_the_sensors_and_the_runs_see_them(tmp_path):
    """``tune --robust``'s batches draw each sensor's offset (absolute, A) and gain (relative) from the same
    ``[tolerances]``; a batch's scenario runs the drawn sensors (an offset shows as the d-current ripple at
    the electrical frequency the controller corrects against)."""
    from pmsmjax.assemble import spec_drive
    from pmsmjax.io.drive_files import drive_spec
    from tuning.autotune import drive_scaling
    from tuning.autotune.objectives import batch_metrics
    from tuning.autotune.scenario_batches import make_batch

    path = tmp_path / "drive.toml"
    path.write_text(DRIVE)
    spec = drive_spec(str(path))
    spread = drive_scaling.plant_spread(spec)
    assert spread == {"R": 0.1, "current_offset_a": 0.05, "current_gain": 0.01}
    batch = make_batch(6, 2, duration_s=(0.02, 0.02), plant_spread=spread, Ts=spec.Ts)
    offsets, gains = (
        np.asarray(batch.plant_scale["current_offset_a"]),
        np.asarray(batch.plant_scale["current_gain"]),
    )
    assert offsets.shape == gains.shape == (6, 3)
    assert np.all(np.abs(offsets) <= 0.05) and np.ptp(offsets[:, 0]) > 0.02
    assert np.all(np.abs(gains - 1.0) <= 0.01)
    drive = spec_drive(spec)
    drawn = batch_metrics(drive, batch)
    nominal = batch_metrics(
        drive, make_batch(6, 2, duration_s=(0.02, 0.02), plant_spread={"R": 0.1}, Ts=spec.Ts)
    )
    assert all(np.all(np.isfinite(np.asarray(v))) for v in drawn.values())
    # Same scenarios and R draws, other sensors: the runs differ.
    assert not np.allclose(np.asarray(drawn["itae"]), np.asarray(nominal["itae"]), rtol=1e-6)
