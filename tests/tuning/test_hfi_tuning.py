"""Gradient tuning of the chapter 6 estimators: ``pmsmjax tune --estimator hfi-rotating |
hfi-pulsating | hybrid``.

Independent references: central finite differences of the same loss in float64 (tests/conftest.py) for
the gradient w.r.t. the filter cut-offs, PLL gains and the hybrid's crossover band; the modulo-pi angle
metric against NumPy on a synthetic trace; the command's one-line refusals of careless input.
"""

import types

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers.gradient_check import CentralDifferences, assert_gradient_close

from pmsmjax.cli import main
from pmsmjax.spec.validation import ParameterError
from tuning.autotune.hfi_tuning import MAX_RPM, make_injection_batch
from tuning.autotune.job import run_tune_job
from tuning.autotune.objectives import ObjectiveWeights, scenario_metrics, smoothed_batch_cost
from tuning.autotune.observers import observer_drive, observer_tuning
from tuning.parameters import LogParameterisation

# log-space step of the central differences. The hybrid's loss has kinks: its carrier fade is a clip
# (C^0, :meth:`pmsmjax.estimators.hybrid.HybridEstimator.injection_scale`), so a period whose scheduling
# speed lies within the step of a fade edge makes the difference one-sided. Measured on its scenario:
# with a step of 1e-5 (1e-4, 1e-3) the difference for injection_off_speed is 2.1 % (3.0 %, 3.2 %) off the
# gradient, and with 1e-6 every component agrees within 2.5e-6: the gradient is the loss's derivative
# where it has one, and the kink is the fade's, not a defect of the gradient.
H = {"hfi-rotating": 1e-5, "hfi-pulsating": 1e-5, "hybrid": 1e-6}
# one "slow" scenario each (1200 periods: warm-up 20 ms, speed step at 40 ms, load step at 66-84 ms);
# the hybrid's (seed 1: about 7 -> 270 r/min) crosses its whole band (50-150 r/min, carrier off at 250),
# so that every edge of the band enters the loss
SEEDS = {"hfi-rotating": 0, "hfi-pulsating": 0, "hybrid": 1}


@pytest.mark.slow
@pytest.mark.parametrize("name", list(SEEDS))
def test_gradient_matches_central_differences(name):
    batch = make_injection_batch(
        1, SEEDS[name], max_rpm=MAX_RPM[name], duration_s=(0.12, 0.12), kinds=("slow",)
    )
    tuning = observer_tuning(name)
    drive = observer_drive(name, n_substeps=1)
    weights = ObjectiveWeights(**tuning.weights)
    param = LogParameterisation(drive, tuning.names, (0.05, 20.0))
    n = len(param.names)

    def loss(theta):
        return smoothed_batch_cost(param.apply(drive, theta), batch, weights)[0]

    stencil = CentralDifferences.around(np.zeros(n), rel_step=H[name], labels=param.names)
    points = np.concatenate([np.zeros((1, n)), stencil.points()])
    values, grads = jax.jit(jax.vmap(jax.value_and_grad(loss)))(jnp.asarray(points))
    values, grads = np.asarray(values), np.asarray(grads)
    g = grads[0]
    fd = stencil.quotients(values[1:])
    assert_gradient_close(g, fd, names=stencil.names, x=stencil.x, rtol=1e-4, value=values[0])
    # every parameter moves the loss (a zero gradient would make the check above vacuous)
    assert np.all(np.abs(g) > 1e-6 * values[0]), (name, dict(zip(param.names, g, strict=True)))


@pytest.mark.slow
def test_angle_metric_modulo_pi_matches_numpy():
    """Modulo pi: the error wrapped to +-pi/2 and the chord ``sin(e)``; an estimate off by pi scores 0."""
    rng = np.random.default_rng(0)
    n = 400
    t = np.arange(n) * 1e-4
    theta = rng.uniform(-np.pi, np.pi, n)
    err = rng.normal(0.0, 0.3, n) + np.pi * rng.integers(0, 2, n)  # half of them on the other pole
    trace = types.SimpleNamespace(
        t=jnp.asarray(t),
        speed_ref=jnp.zeros(n),
        omega_m=jnp.zeros(n),
        i_abc=jnp.zeros((n, 3)),
        u_dq_ref=jnp.zeros((n, 2)),
        torque=jnp.zeros(n),
        theta_e=jnp.asarray(theta),
        theta_e_est=jnp.asarray(theta + err),
    )
    m = scenario_metrics(trace, 0.04, 0.03, 15.0, 300.0, observe_from_s=0.01, angle_modulo=np.pi)
    keep = (t >= 0.01 - 1e-12) & (t < 0.04 - 1e-12)
    wrapped = (err[keep] + np.pi / 2) % np.pi - np.pi / 2
    assert np.max(np.abs(wrapped)) < np.pi / 2
    assert float(m["angle_error_rms_rad"]) == pytest.approx(np.sqrt(np.mean(wrapped**2)), rel=1e-10)
    assert float(m["angle_chord_rms_rad"]) == pytest.approx(
        np.sqrt(np.mean(np.sin(err[keep]) ** 2)), rel=1e-10
    )
    # modulo 2 pi (the default) sees the flipped half as ~pi off
    full = scenario_metrics(trace, 0.04, 0.03, 15.0, 300.0, observe_from_s=0.01)
    assert float(full["angle_error_rms_rad"]) > 1.0 > 0.5 > float(m["angle_error_rms_rad"])


def test_injection_batches_are_low_speed_and_scored_modulo_pi():
    batch = make_injection_batch(16, 0)
    assert batch.angle_modulo == pytest.approx(np.pi) and set(batch.kind) == {"standstill", "slow"}
    refs = np.asarray(batch.scenarios.speed_ref.values)
    assert np.max(np.abs(refs)) <= np.radians(100 * 6.0) + 1e-12  # +-100 r/min in rad/s
    still = np.array([k == "standstill" for k in batch.kind])
    assert np.all(refs[still] == 0) and np.all(np.asarray(batch.initial_speed_m)[still] == 0)
    loads = np.asarray(batch.scenarios.load_torque.values)[:, -1]
    assert np.all(np.abs(loads[still]) >= 2.0)
    assert np.max(np.abs(np.asarray(batch.initial_theta_e))) <= np.radians(60.0)
    with pytest.raises(ParameterError, match="kinds must be"):
        make_injection_batch(2, 0, kinds=("step",))


def test_careless_input_is_refused_in_one_line(tmp_path, capsys):
    with pytest.raises(SystemExit):
        main(["tune", "--estimator", "hfi-rotatin", "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "--estimator" in err and "hfi-rotating" in err
    with pytest.raises(ParameterError, match="--estimator hybrid tunes an observer on the three-phase FOC"):
        run_tune_job(tmp_path, estimator="hybrid", control="smc", n_train=1, n_heldout=1)
    with pytest.raises(SystemExit):
        main(["tune", "--estimator", "hfi-pulsating", "--train", "0", "--out", str(tmp_path / "y")])
    assert "--train" in capsys.readouterr().err.strip().splitlines()[-1]


@pytest.mark.slow
def test_command_writes_its_outputs_with_angles_modulo_pi(tmp_path):
    """``pmsmjax tune --estimator hfi-pulsating``: gains.toml (the tuned names), result.json (angle errors
    modulo pi, the injection kinds, the stability verdict), the figures and the checkpoint."""
    import json

    from tuning.parameters import read_gains_toml

    out = tmp_path / "tune"
    args = ["tune", "--estimator", "hfi-pulsating", "--out", str(out), "--train", "1", "--heldout", "1"]
    args += ["--iterations", "1", "--duration-s", "0.12", "0.12", "--eval-substeps", "1", "--no-progress"]
    assert main(args) == 0
    data = json.loads((out / "result.json").read_text())
    assert data["estimator"] == "hfi-pulsating" and data["stability"] == "stable"
    assert data["config"]["kinds"] == ["standstill", "slow"]
    for part in ("train", "heldout"):
        for when in ("before", "after"):
            assert 0 < data[part][when]["angle_error_rms_rad"] < np.pi / 2  # modulo pi
    assert set(read_gains_toml(out / "gains.toml")) == set(observer_tuning("hfi-pulsating").names)
    for name in ("cost.png", "responses.png", "checkpoint.npz"):
        assert (out / name).stat().st_size > 0


def test_injection_on_a_flux_map_file_is_tuned_within_its_region():
    """saturated-ipm: its linear model at the rated current (L_q below L_d) no longer refuses it; the
    injection is designed on the map at no load, runs map-compensated, its gains are named through the
    wrapper, and its loads stop at the injection region's torque (the hybrid's at the rated one)."""
    from pmsmjax.estimators.hfi_cross_saturation import CrossSaturationCompensated
    from pmsmjax.estimators.injection_region import spec_injection_region
    from pmsmjax.io.drive_files import drive_spec as _drive_spec
    from tuning.autotune.drive_batches import drive_batches as _drive_batches
    from tuning.autotune.observers import tuned_names as _tuned_names
    from tuning.parameters import get_leaf

    spec = _drive_spec("saturated-ipm")
    assert spec.motor["L_q"] < spec.motor["L_d"]
    drive = observer_drive("hfi-pulsating", spec=spec)
    assert isinstance(drive.estimator.observer, CrossSaturationCompensated)
    names = _tuned_names("hfi-pulsating", drive)
    assert names[0] == "estimator.observer.injection.bandpass_bandwidth"
    assert all(float(get_leaf(drive, n)) > 0 for n in names)
    assert drive.estimator.observer.injection.L_q > drive.estimator.observer.injection.L_d
    region = spec_injection_region(spec)
    assert _drive_batches(spec, "hfi-pulsating").ranges["load_nm"] == (0.0, region.max_torque_nm)
    assert _drive_batches(spec, "hybrid").ranges["load_nm"] == (0.0, spec.ratings["rated_torque_nm"])
