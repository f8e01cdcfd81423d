"""``[operating]`` in Monte Carlo studies and robust tuning: the bands are drawn uniformly, next to the
``[tolerances]``, through the same machinery (study parameters, batch plant factors), and a drawn warm
motor starts at its drawn winding temperature."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from pmsmjax.io.drive_files import PRESET_FOLDER, drive_spec
from pmsmjax.simulate import simulate
from tuning.autotune import drive_scaling
from tuning.autotune.scenario_batches import make_batch
from tuning.montecarlo import study as mc_study
from tuning.montecarlo.distributions import sample

BOOK = (PRESET_FOLDER / "book.toml").read_text()
WARM = """
[thermal]
r_th_k_per_w = 0.5
c_th_j_per_k = 1500.0
initial_c = 70.0

[operating]
winding_temperature_c = [20.0, 120.0]
u_dc_v = [280.0, 330.0]
ambient_c = [0.0, 40.0]
"""


@pytest.fixture(scope="module")
def warm_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("warm") / "warm.toml"
    path.write_text(BOOK + WARM)
    return str(path)


def test_study_draws_the_operating_bands(warm_file):
    study = mc_study.Study(motor=warm_file, n=64, duration_s=0.01, load_time_s=0.005)
    params = study.parameters
    assert params["motor.R"] == {"distribution": "uniform", "tolerance": 0.2}  # [tolerances] kept
    drive = mc_study.build_drive(study)
    drawn = sample(mc_study.distributions(study, drive), 64, 0)
    for name, (low, high) in (
        ("thermal.initial_k", (293.15, 393.15)),
        ("thermal.ambient_k", (273.15, 313.15)),
        ("bridge.u_dc", (280.0, 330.0)),  # the band replaces the +-10 % tolerance of u_dc_v
    ):
        x = drawn[name]
        assert low <= x.min() and x.max() <= high, name
        assert x.max() - x.min() > 0.8 * (high - low), name  # the whole band, not a corner
    names = tuple(drawn)
    values = jnp.asarray(np.stack([drawn[n] for n in names], 1)[:3])

    def start_temperature(row):
        d, scenario = mc_study.apply_sample(drive, study, names, row)
        return simulate(d, scenario).winding_temperature[0]

    np.testing.assert_allclose(
        np.asarray(jax.vmap(start_temperature)(values)), drawn["thermal.initial_k"][:3], rtol=1e-6
    )


@pytest.mark.slow
def test_robust_tuning_batches_draw_the_operating_bands(warm_file):
    from tuning.autotune.objectives import batch_metrics

    spec = drive_spec(warm_file)
    spread = drive_scaling.plant_spread(spec)
    assert spread["R"] == 0.2 and spread["u_dc_v"] == pytest.approx((280 / 311, 330 / 311))
    assert spread["initial_k"] == pytest.approx((293.15 / 343.15, 393.15 / 343.15))
    batch = make_batch(4, 1, duration_s=(0.01, 0.01), plant_spread=spread, Ts=spec.Ts)
    start_k = 343.15 * np.asarray(batch.plant_scale["initial_k"])
    assert np.all((293.15 <= start_k) & (start_k <= 393.15))
    from pmsmjax.assemble import spec_drive

    metrics = batch_metrics(spec_drive(spec), batch)
    assert all(np.all(np.isfinite(np.asarray(v))) for v in metrics.values())
