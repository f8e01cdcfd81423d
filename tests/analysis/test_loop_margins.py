"""Loop linearisation and margins: the margins of a loop known in closed form, their gradients by finite
differences, the injection hooks leaving a run unchanged when absent or zero, the refusals, and (slow) the
linearised loop transfer against a sine sweep of the nonlinear drive for both loops of the book drive and the
two-mass servo."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.optimize import brentq

from pmsmjax.analysis.loop_linearisation import LinearDrive, check_linearisable
from pmsmjax.analysis.margins import loop_margins
from pmsmjax.assemble import spec_drive
from pmsmjax.io.drive_files import drive_spec
from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.simulate import simulate
from pmsmjax.spec.validation import ParameterError

TS = 1e-4


def toy_loop(K) -> LinearDrive:
    """The speed channel closed around ``L(z) = K / (z (z - 1))`` (an integrator and a period's delay):
    ``s' = s + v``, ``d' = s``, ``y = -K d``, ``v = y + w``; the current channel left empty."""
    K = jnp.asarray(K, jnp.float64)
    A = jnp.array([[1.0, 0.0], [1.0, 0.0]]) + jnp.array([[0.0, -1.0], [0.0, 0.0]]) * K
    B = jnp.array([[0.0, 1.0], [0.0, 0.0]])
    C = jnp.array([[0.0, 0.0], [0.0, -1.0]]) * K
    return LinearDrive(A, B, C, jnp.zeros((2, 2)), jnp.zeros(2), jnp.zeros(()), TS)


def toy_l(K, f):
    z = np.exp(2j * np.pi * np.asarray(f) * TS)
    return K / (z * (z - 1.0))


def test_margins_of_a_known_loop():
    K = 0.2
    m = loop_margins(toy_loop(K), "speed")
    f_c = brentq(lambda f: abs(toy_l(K, f)) - 1.0, 1.0, 4000.0)
    pm = 180.0 + np.degrees(np.angle(toy_l(K, f_c)))
    # the phase crossover: arg L = -180 deg where the delay and integrator lag sum to 180: f = 1 / (6 Ts)
    f_p = brentq(lambda f: np.imag(toy_l(K, f)), 100.0, 4990.0)
    gm = -20 * np.log10(abs(toy_l(K, f_p)))
    f = np.linspace(1.0, 4999.0, 200001)
    ms = np.max(np.abs(1.0 / (1.0 + toy_l(K, f))))
    assert float(m.crossover_hz) == pytest.approx(f_c, rel=1e-3)
    assert float(m.phase_margin_deg) == pytest.approx(pm, abs=0.05)
    assert float(m.gain_margin_db) == pytest.approx(gm, abs=0.05)
    assert float(m.sensitivity_peak) == pytest.approx(ms, rel=2e-3)
    np.testing.assert_allclose(
        np.asarray(toy_loop(K).loop_transfer("speed", [50.0, 700.0])), toy_l(K, [50.0, 700.0])
    )
    assert toy_loop(K).spectral_radius() < 1.0 and toy_loop(1.2).spectral_radius() > 1.0


def test_margin_gradients_match_finite_differences():
    for name in ("phase_margin_deg", "sensitivity_peak", "crossover_hz"):
        f = lambda k, name=name: getattr(loop_margins(toy_loop(k), "speed"), name)
        g = float(jax.grad(f)(0.2))
        h = 1e-5
        fd = (float(f(0.2 + h)) - float(f(0.2 - h))) / (2 * h)
        assert g == pytest.approx(fd, rel=2e-3), name


@pytest.fixture(scope="module")
def book():
    return spec_drive(drive_spec("book"), "pi")


def test_zero_or_absent_injection_is_the_same_run(book):
    base = Scenario(0.01, speed_ref=Profile.constant(50.0), load_torque=Profile.constant(2.0))
    zero = Scenario(
        0.01,
        speed_ref=Profile.constant(50.0),
        load_torque=Profile.constant(2.0),
        measured_iq_perturbation=Profile.constant(0.0),
        iq_ref_perturbation=Profile.constant(0.0),
    )
    a, b = simulate(book, base), simulate(book, zero)
    for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    pushed = simulate(
        book, Scenario(0.01, speed_ref=Profile.constant(50.0), iq_ref_perturbation=Profile.constant(1.0))
    )
    assert float(pushed.i_dq_ref[-1, 1] - a.i_dq_ref[-1, 1]) != 0.0


def test_refusals(book):
    with pytest.raises(ParameterError, match="voltage limit"):
        check_linearisable(book, 3000 * np.pi / 30, 0.0)
    with pytest.raises(ParameterError, match="current\n?.*limit|current limit"):
        check_linearisable(book, 50.0, 100.0)
    with pytest.raises(ParameterError, match="control 'pi'"):
        check_linearisable(spec_drive(drive_spec("book"), "smc"), 50.0, 1.0)


def test_tune_refuses_margins_for_an_observer(tmp_path):
    from tuning.autotune.job import run_tune_job

    with pytest.raises(ParameterError, match="min-phase-margin-deg"):
        run_tune_job(tmp_path, estimator="smo", min_phase_margin_deg=40.0, n_train=1, n_heldout=1)


@pytest.mark.slow
@pytest.mark.parametrize(
    "preset, speed_m, load_nm",
    [("book", 90.0, 5.0), ("servo-two-mass", 35.0, 0.7)],
)
def test_linearisation_matches_sine_sweep(preset, speed_m, load_nm):
    from pmsmjax.analysis.loop_linearisation import linearise
    from pmsmjax.analysis.loop_sweep import sweep_loop

    drive = spec_drive(drive_spec(preset), "pi")
    lin = linearise(drive, speed_m, load_nm)
    assert float(lin.residual) < 1e-8 and lin.spectral_radius() < 1.0
    freqs = [10.0, 40.0, 150.0, 200.0, 600.0, 2000.0]  # up to a fifth of the 10 kHz control rate
    for loop in ("current", "speed"):
        f, measured = sweep_loop(drive, loop, speed_m, load_nm, freqs, amplitude_a=0.1)
        model = np.asarray(lin.loop_transfer(loop, f))
        db = 20 * np.log10(np.abs(measured / model))
        deg = np.degrees(np.angle(measured / model))
        assert np.max(np.abs(db)) < 0.5 and np.max(np.abs(deg)) < 3.0, (loop, db, deg)


@pytest.mark.slow
def test_drive_margin_gradient_matches_finite_differences():
    """d(speed-loop phase margin)/d(speed kp) through the whole linearisation (Newton steps, Jacobians,
    interpolated crossover) against central differences, on the two-mass servo."""
    import equinox as eqx

    from pmsmjax.analysis.loop_linearisation import linearise_traced

    drive = spec_drive(drive_spec("servo-two-mass"), "pi")

    @eqx.filter_jit
    def pm(kp):
        d = eqx.tree_at(lambda d: d.controller.speed.kp, drive, kp)
        return loop_margins(
            linearise_traced(d, jnp.asarray(35.0), jnp.asarray(0.7)), "speed"
        ).sensitivity_peak

    kp = drive.controller.speed.kp
    g = float(jax.grad(pm)(kp))
    h = 1e-4 * float(kp)
    fd = (float(pm(kp + h)) - float(pm(kp - h))) / (2 * h)
    assert g == pytest.approx(fd, rel=1e-3)


def test_angle_dependent_parts_are_left_out_of_the_linearisation(book):
    """Harmonics, cogging and the inverter's error voltage make the steady state a periodic orbit even in the
    rotor frame: the drive is linearised as its fundamental wave, the same matrices as the drive without
    them (and a drive that has them still gets a converged fixed point)."""
    from pmsmjax.analysis.loop_linearisation import fundamental_wave, linearise
    from pmsmjax.assemble import with_parts
    from pmsmjax.inverters.averaged import AveragedBridge
    from pmsmjax.machines.harmonics import MagnetHarmonics

    rippled = with_parts(
        book,
        {
            "machine.harmonics": MagnetHarmonics.from_rows([[5, 0.0019, 0.4]], [[6, 0.045, 0.3]]),
            "bridge": AveragedBridge(book.bridge.u_dc, dead_time=2e-6, device_drop=1.0),
        },
    )
    assert rippled.machine.harmonics is not None and rippled.bridge.voltage_error is not None
    bare = fundamental_wave(rippled)
    assert bare.machine.harmonics is None and bare.bridge.voltage_error is None
    a, b = linearise(rippled, 90.0, 5.0), linearise(book, 90.0, 5.0)
    assert float(a.residual) < 1e-8
    np.testing.assert_allclose(np.asarray(a.A), np.asarray(b.A), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(np.asarray(a.B), np.asarray(b.B), rtol=1e-12, atol=1e-12)
