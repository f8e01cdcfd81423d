"""The tune job on a drive file: on the book drive its drives and batches are the book's to the bit
(against the batches and drives built from the book's explicit numbers); on other drives the batches span
the file's ranges at its control period, and the plant draws stay within its tolerances."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from pmsmjax import presets
from pmsmjax.assemble import spec_drive
from pmsmjax.estimators.sensored_warmup import SensoredWarmup
from pmsmjax.io.drive_files import drive_spec
from pmsmjax.machines.saturation import saturated_machine
from pmsmjax.presets.control_methods import control_drive
from pmsmjax.units import rad_s_to_rpm
from tuning.autotune import drive_scaling
from tuning.autotune.drive_batches import drive_batches
from tuning.autotune.hfi_tuning import make_injection_batch
from tuning.autotune.observers import make_observer_batch, observer_drive, observer_tuning
from tuning.autotune.scenario_batches import make_batch
from tuning.parameters import get_leaf, set_leaves


def same(a, b) -> bool:
    """Every leaf bit-identical and the static parts equal."""
    la, ta = jax.tree.flatten(a)
    lb, tb = jax.tree.flatten(b)
    return ta == tb and all(np.array_equal(x, y) for x, y in zip(la, lb, strict=True))


@pytest.fixture(scope="module")
def book():
    return drive_spec("book")


def test_book_control_batches_are_the_book_numbers(book):
    batches = drive_batches(book)
    explicit = make_batch(
        24, 5, speed_rpm=(200.0, 1500.0), load_nm=(0.0, 10.0), duration_s=(0.3, 0.5), Ts=1e-4
    )
    assert same(batches.make(24, 5, duration_s=batches.duration_s), explicit)
    spread = {"J": 0.5, "R": 0.2}
    assert same(
        batches.make(6, 1, duration_s=batches.duration_s, plant_spread=spread),
        make_batch(6, 1, speed_rpm=(200.0, 1500.0), load_nm=(0.0, 10.0), duration_s=(0.3, 0.5),
                   plant_spread=spread, Ts=1e-4),
    )  # fmt: skip


@pytest.mark.parametrize(
    "estimator, explicit",
    [
        ("smo", lambda n, s: make_observer_batch(n, s, speed_rpm=(100.0, 2000.0), start_rpm=(500.0, 2000.0),
                                                 load_nm=(0.0, 10.0), duration_s=(0.15, 0.25), Ts=1e-4)),
        ("hfi-pulsating", lambda n, s: make_injection_batch(n, s, max_rpm=100.0, load_nm=(0.0, 10.0),
                                                            duration_s=(0.15, 0.25), Ts=1e-4)),
        ("hybrid", lambda n, s: make_injection_batch(n, s, max_rpm=300.0, duration_s=(0.15, 0.25))),
    ],
)  # fmt: skip
def test_book_observer_batches_are_the_book_numbers(book, estimator, explicit):
    batches = drive_batches(book, estimator)
    assert batches.warmup_s == 0.02
    kinds = ("step", "reversal") if estimator == "smo" else ("standstill", "slow")
    assert same(batches.make(12, 3, duration_s=batches.duration_s, kinds=kinds), explicit(12, 3))


@pytest.mark.parametrize("control", ["pi", "smc", "pr", "smc-dtc"])
def test_book_control_drives_are_the_presets(book, control):
    assert same(spec_drive(book, control, n_substeps=1), control_drive(control, n_substeps=1))


@pytest.mark.parametrize(
    "n_phases, control", [(6, "vsd"), (6, "double-dq"), (6, "pr"), (5, "vsd"), (5, "conventional")]
)
def test_book_multiphase_drives_are_the_presets(n_phases, control):
    from pmsmjax.presets.five_phase import five_phase_drive
    from pmsmjax.presets.six_phase import six_phase_drive

    preset = six_phase_drive if n_phases == 6 else five_phase_drive
    spec = drive_spec("book", n_phases=n_phases)
    assert same(spec_drive(spec, control, n_substeps=1), preset(control=control, n_substeps=1))


def _book_observer_drive(name):
    """The observer drive as built from the book presets (the sensorless preset behind the warm-up)."""
    if observer_tuning(name).chapter6:
        motor = presets.book_motor(salient=True)
        options = {"polarity": False} if name == "hybrid" else {}
        drive = presets.sensorless_drive(name, motor, observer_options=options, n_substeps=1)
        drive = eqx.tree_at(lambda d: d.machine, drive, saturated_machine(motor))
    else:
        drive = presets.sensorless_drive(name, n_substeps=1)
    drive = eqx.tree_at(lambda d: d.estimator, drive, SensoredWarmup(drive.estimator, 0.02, 0.05, 0.25))
    names = [n for n in observer_tuning(name).names if not isinstance(get_leaf(drive, n), jnp.ndarray)]
    return set_leaves(drive, names, [jnp.asarray(get_leaf(drive, n), jnp.float64) for n in names])


@pytest.mark.parametrize("name", ["smo", "ekf", "hfi-rotating", "hybrid"])
def test_book_observer_drives_are_the_presets(book, name):
    assert same(observer_drive(name, spec=book, n_substeps=1), _book_observer_drive(name))


@pytest.mark.parametrize("name", ["servo-400w", "industrial-5k6w", "outer-rotor-24v"])
def test_control_batches_span_the_drive_files_ranges(name):
    spec = drive_spec(name)
    batches = drive_batches(spec)
    b = batches.make(40, 2, duration_s=batches.duration_s)
    (v_lo, v_hi), (t_lo, t_hi), (d_lo, d_hi) = (
        spec.tuning[k] for k in ("speed_rpm", "load_nm", "duration_s")
    )
    speed = np.abs(rad_s_to_rpm(np.asarray(b.scenarios.speed_ref.values[:, -1])))
    assert np.all((speed >= v_lo * (1 - 1e-12)) & (speed <= v_hi * (1 + 1e-12)))
    assert speed.min() < v_lo + 0.2 * (v_hi - v_lo) and speed.max() > v_hi - 0.2 * (v_hi - v_lo)
    load = np.abs(np.asarray(b.scenarios.load_torque.values[:, -1]))
    assert np.all((load >= t_lo) & (load <= t_hi)) and load.max() > 0.7 * t_hi
    d = np.asarray(b.duration_s)
    assert np.all((d >= d_lo - spec.Ts / 2) & (d <= d_hi + spec.Ts / 2))
    periods = d / spec.Ts  # whole control periods, and the scan's horizon likewise
    np.testing.assert_allclose(periods, np.round(periods), atol=1e-6)
    assert b.horizon_s / spec.Ts == pytest.approx(round(d_hi / spec.Ts), abs=1e-6)


def test_observer_batches_scale_to_the_drive():
    """outer-rotor-24v: top speed capped by what the 24 V link reaches under the rated torque (835 r/min
    with i_d = 0, below twice the rated 600), loads up to the rated 3 N m, warm-up half the book's."""
    spec = drive_spec("outer-rotor-24v")
    from pmsmjax.spec.steady_state import top_speed_rpm

    reach = top_speed_rpm(spec.motor, spec.voltage_limit_v, 3.0)
    batches = drive_batches(spec, "smo")
    assert batches.ranges["speed_rpm"][1] == pytest.approx(reach) and reach < 2 * 600
    b = batches.make(16, 0, duration_s=batches.duration_s, kinds=("step", "reversal"))
    speeds = np.abs(rad_s_to_rpm(np.asarray(b.scenarios.speed_ref.values)))
    assert speeds.max() <= reach * (1 + 1e-9)
    assert np.abs(np.asarray(b.scenarios.load_torque.values)).max() <= 3.0
    assert batches.warmup_s == pytest.approx(0.02 * 0.15 / 0.3)
    assert np.all(np.asarray(b.observe_from_s) == batches.warmup_s)


def test_plant_draws_stay_within_the_tolerances():
    spec = drive_spec("servo-400w")
    spread = drive_scaling.plant_spread(spec)
    assert spread == {k: v for k, v in spec.tolerances.items()}  # every tolerance, the DC link included
    batches = drive_batches(spec)
    b = batches.make(64, 9, duration_s=batches.duration_s, plant_spread=spread)
    for k, frac in spread.items():
        scale = np.asarray(b.plant_scale[k])
        assert np.all(np.abs(scale - 1.0) <= frac) and np.ptp(scale) > frac  # within, and spread across
    nominal = batches.make(64, 9, duration_s=batches.duration_s)
    assert same(b.scenarios, nominal.scenarios)  # the draws leave the scenarios of a seed unchanged


def test_dc_link_draw_reaches_the_plant_and_its_voltage_limit():
    """A DC-link draw of 0.5 on a scenario that needs more than half the link saturates the voltage where
    the nominal link does not (the book drive at 1500 r/min needs 110 V of its 180 V limit)."""
    from tuning.autotune.objectives import batch_metrics

    drive = presets.book_drive(n_substeps=1)
    b = make_batch(1, 0, speed_rpm=(1500.0, 1500.0), load_nm=(0.0, 0.0), duration_s=(0.12, 0.12))
    low = eqx.tree_at(lambda x: x.plant_scale, b, {"u_dc_v": jnp.asarray([0.5])})
    nominal, starved = batch_metrics(drive, b), batch_metrics(drive, low)
    assert float(nominal["voltage_saturation"][0]) < 0.05 < float(starved["voltage_saturation"][0])
    assert float(starved["itae"][0]) > float(nominal["itae"][0])


def test_worst_decile_is_the_mean_of_the_worst_tenth():
    costs = np.random.default_rng(0).lognormal(size=37)
    k = 4  # ceil(0.1 x 37)
    assert drive_scaling.worst_share_mean(costs) == pytest.approx(np.sort(costs)[-k:].mean(), rel=1e-15)
    assert drive_scaling.worst_share_mean(costs) >= costs.mean()
    assert drive_scaling.worst_share_mean([2.0, 1.0]) == 2.0  # at least one scenario


def test_penalty_weights_follow_the_drives_itae_scale():
    """The ITAE of a step at the current limit grows as w t_a^2 (benchmarks/user_drive_tuning.py's
    floor): the penalty weights scale with speed x time^2, exactly 1 on the book drive."""
    from tuning.autotune.objectives import ObjectiveWeights

    w = ObjectiveWeights(angle_error=10.0)
    assert drive_scaling.scaled_weights(w, drive_spec("book")) is w
    spec = drive_spec("industrial-5k6w")
    scale = (1750.0 / 1000.0) * (spec.tuning["duration_s"][0] / 0.3) ** 2
    scaled = drive_scaling.scaled_weights(w, spec)
    for name in ("overshoot", "current_penalty", "voltage_saturation_penalty", "angle_error"):
        assert getattr(scaled, name) == pytest.approx(getattr(w, name) * scale, rel=1e-12)
    assert scaled.itae == w.itae and scaled.current_smoothing_a == w.current_smoothing_a
