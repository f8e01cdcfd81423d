"""HF-injection estimators of chapter 6 (``hfi-rotating``, ``hfi-pulsating``) on the salient book motor.

References, independent of the code under test: the plant's true angle (sensorless closed loop at
standstill under 10 N m and through a 0 -> 60 -> -60 r/min reversal, scored modulo pi); the book's
continuous-time HF model worked out by hand for the demodulated error signal, ``I_n sin(2 dth)`` with
``I_n = (L_q - L_d) V_h / (2 L_d L_q w_h)``, with the rotor held at known offsets; a DFT of the current
loop's command at the carrier frequency, with and without the carrier kept out of the feedback; and
central finite differences for the gradients of a closed-loop angle-error loss.

Modules: pmsmjax/estimators/hfi_rotating.py, hfi_pulsating.py, hfi_signal.py.
"""

import functools
import json
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers.gradient_check import check_gradient

from pmsmjax import ParameterError, presets
from pmsmjax.cli import main
from pmsmjax.drive import PeriodInputs
from pmsmjax.estimators import INJECTION_OBSERVERS, make_observer
from pmsmjax.estimators.pll import PLL
from pmsmjax.frames.three_phase import abc_to_alpha_beta
from pmsmjax.io.logs import write_csv_atomic
from pmsmjax.recorded.offline_observer import angle_error_modulo_pi
from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.simulate import simulate
from pmsmjax.units import rpm_to_rad_s

MOTOR = presets.book_motor(salient=True)
TS = presets.BOOK_TS
METHODS = tuple(INJECTION_OBSERVERS)
#: The accuracy limit: electrical degrees RMS, modulo pi.
LIMIT_RMS_DEG = 5.0
#: Loss of lock: the modulo-pi error reaching 45 degrees (half-way to the unstable equilibrium).
LOCK_DEG = 45.0
SETTLE_S = 0.05
DURATION_S = 0.8
W60 = rpm_to_rad_s(60.0)


def hfi_drive(method: str, mechanics="dynamic", mode="speed", **options):
    drive = presets.book_drive(MOTOR, mechanics=mechanics, mode=mode)
    return presets.with_observer(drive, method, MOTOR, options, startup=False)


def scenarios() -> dict:
    """Same length and breakpoint count, so one compiled drive serves both."""
    standstill = Scenario(
        duration_s=DURATION_S,
        speed_ref=Profile.piecewise([0.0, 0.1, 0.2, 0.3, 0.4, 0.5], [0.0] * 6, "linear"),
        load_torque=Profile.step(0.1, 0.0, 10.0),
    )
    reversal = Scenario(
        duration_s=DURATION_S,
        speed_ref=Profile.piecewise(
            [0.0, 0.05, 0.15, 0.3, 0.6, 0.8], [0.0, 0.0, W60, W60, -W60, -W60], "linear"
        ),
        load_torque=Profile.step(0.1, 5.0, 5.0),
    )
    return {"standstill, 10 N m step": standstill, "0 -> 60 -> -60 r/min, 5 N m": reversal}


@functools.cache
def closed_loop(method: str) -> dict:
    """Sensorless runs from a rotor 30 degrees off the estimator's initial angle."""
    drive = hfi_drive(method)
    out = {}
    for name, sc in scenarios().items():
        tr = simulate(drive, sc, initial_state=drive.init(theta_e=math.radians(30.0)))
        out[name] = tr
    return out


@pytest.mark.slow
@pytest.mark.parametrize("method", METHODS)
def test_angle_error_standstill_load_and_reversal(method):
    for name, tr in closed_loop(method).items():
        t = np.asarray(tr.t)
        e = np.degrees(np.asarray(angle_error_modulo_pi(tr.theta_e_est, tr.theta_e)))
        keep = t >= SETTLE_S
        rms = float(np.sqrt(np.mean(e[keep] ** 2)))
        worst = float(np.max(np.abs(e)))
        assert rms < LIMIT_RMS_DEG, f"{method}, {name}: {rms:.2f} deg RMS"
        assert worst < LOCK_DEG, f"{method}, {name}: lost lock ({worst:.1f} deg)"
        # the drive did what was asked: speed back on its reference at the end, torque carried
        speed_err = abs(float(tr.speed_rpm[-1] - tr.speed_ref_rpm[-1]))
        assert speed_err < 5.0, f"{method}, {name}: speed off by {speed_err:.1f} r/min at the end"
        if name.startswith("standstill"):
            # mean over the last 20 ms: the carrier's current makes a torque ripple at w_h
            torque = float(np.mean(np.asarray(tr.torque)[-200:]))
            assert abs(torque - 10.0 - float(MOTOR.B) * float(tr.omega_m[-1])) < 0.2, torque


#: Rotor offsets from the (held) estimate, electrical rad.
OFFSETS = tuple(np.radians([-40.0, -20.0, -5.0, 5.0, 20.0, 40.0]))


@functools.cache
def held(method: str, filter_feedback=True, n=400):
    """The rotor held at :data:`OFFSETS` (imposed zero speed, zero current references), the PLL slowed to
    a crawl so the estimate stays where it starts: the low-passed error signal (A, mean over the last 10
    carrier periods), the estimator's output angle (rad), the controller's voltage commands ``(n, 2)``
    and the output angle's spread over the last 200 periods (rad), per offset."""
    drive = hfi_drive(method, mechanics="imposed", mode="current", filter_feedback=filter_feedback)
    drive = eqx.tree_at(lambda d: d.estimator.pll, drive, PLL(1e-9, 1e-12))
    zeros = jnp.zeros(n)
    xs = PeriodInputs(zeros, zeros, zeros, zeros)

    @jax.jit
    @jax.vmap
    def run(theta):
        def body(s, x):
            s, rec = drive.step(s, x)
            return s, (rec, s.estimator.error)

        _, (rec, error) = jax.lax.scan(body, drive.init(theta_e=theta), xs)
        # the error's 2 w_h ripple (a sixth of it passes the low-pass) averages out over whole carrier
        # periods (10 samples each)
        theta_est = rec.estimate[-200:, 0]
        return jnp.mean(error[-100:]), theta_est[-1], rec.u_dq_ref, jnp.ptp(theta_est)

    return run(jnp.asarray(OFFSETS))


@pytest.mark.slow
@pytest.mark.parametrize("method", METHODS)
def test_error_signal_matches_small_angle_model(method):
    """``eps = I_n sin(2 dth)``, ``I_n`` from L_d, L_q, V_h, w_h (the book's continuous HF model)."""
    offsets = np.asarray(OFFSETS)
    error, theta_est, _, spread = held(method)
    est = make_observer(method, MOTOR, TS)
    w_h, v_h = float(est.hf_omega), float(est.hf_voltage)
    L_d, L_q = float(MOTOR.L_d), float(MOTOR.L_q)
    amplitude = (L_q - L_d) * v_h / (2.0 * L_d * L_q * w_h)
    predicted = amplitude * np.sin(2.0 * (offsets - np.asarray(theta_est)))
    # the estimate did stay put (the rotating method's output carries its constant compensation of the
    # resistance's phase, about 1.2 degrees)
    assert np.max(np.asarray(spread)) < 1e-6 and np.max(np.abs(np.asarray(theta_est))) < math.radians(2.0)
    np.testing.assert_allclose(np.asarray(error), predicted, rtol=0.05)
    if method == "hfi-pulsating":
        # and exactly the held carrier's amplitude: the flux of a carrier held over periods Ts is V_h over
        # 2 sin(w_h Ts / 2) / Ts, 1.6 % below w_h at 1 kHz (hfi_signal docstring); the resistance's
        # 0.05 % is what is left
        w_eff = 2.0 * math.sin(0.5 * w_h * TS) / TS
        np.testing.assert_allclose(np.asarray(error), predicted * w_h / w_eff, rtol=2e-3)


def test_current_loop_keeps_the_carrier_out():
    """The current loop's command at the carrier frequency: with the estimator's notch-filtered current
    in the feedback, under 1 % of V_h; with the raw current (carrier in the loop) many times more."""
    est = make_observer("hfi-rotating", MOTOR, TS)
    n_carrier = round(2.0 * math.pi / (float(est.hf_omega) * TS))  # 10 samples a carrier period
    k = np.arange(20 * n_carrier)

    def carrier_amplitude(u_dq):
        u = np.asarray(u_dq)[:, -k.size :, :]  # (offsets, periods, dq)
        phasor = np.exp(-2j * np.pi * k / n_carrier)
        return float(np.max(np.abs(2.0 * np.mean(u * phasor[None, :, None], axis=1))))

    v_h = float(est.hf_voltage)
    filtered = carrier_amplitude(held("hfi-rotating")[2])
    raw = carrier_amplitude(held("hfi-rotating", filter_feedback=False)[2])
    assert filtered < 0.01 * v_h, filtered
    assert raw > 0.05 * v_h and raw > 20 * filtered, (raw, filtered)


@pytest.mark.slow
@pytest.mark.parametrize("method", METHODS)
def test_gradients_of_filter_and_pll_gains(method):
    """d(mean squared angle error)/d(gain), closed loop from 20 degrees off, against central differences."""
    drive = hfi_drive(method, mechanics="imposed", mode="current")
    n = 300
    zeros = jnp.zeros(n)
    xs = PeriodInputs(zeros + 0.3 * W60, zeros, zeros, zeros + 2.0)
    theta0 = math.radians(20.0)
    names = ["bandpass_bandwidth", "error_cutoff", "pll.kp", "pll.ki"]
    if method == "hfi-rotating":
        names.append("sequence_cutoff")

    def get(est, name):
        return est.pll.kp if name == "pll.kp" else est.pll.ki if name == "pll.ki" else getattr(est, name)

    def loss(gains):
        est = drive.estimator
        for name, g in zip(names, gains, strict=True):
            est = eqx.tree_at(lambda e, name=name: get(e, name), est, g)
        d = eqx.tree_at(lambda d: d.estimator, drive, est)
        _, rec = jax.lax.scan(lambda s, x: d.step(s, x), d.init(speed_m=0.3 * W60, theta_e=theta0), xs)
        e = angle_error_modulo_pi(rec.estimate[:, 0], rec.machine.theta_e)
        return jnp.mean(e**2)

    g0 = jnp.stack([get(drive.estimator, name) for name in names])
    grad = jax.jit(jax.grad(loss))(g0)
    r = check_gradient(
        jax.jit(loss), g0, grad=grad, rel_step=1e-5, step_floor=0.0, rtol=1e-4, atol=1e-16, labels=names
    )
    assert np.all(np.abs(r.fd) > 0.0), r.names  # the loss does depend on every gain


@pytest.mark.slow
def test_observe_cli_on_a_rotating_injection_log(tmp_path):
    """``pmsmjax observe --observer hfi-rotating`` on the reversal log of the rotating-injection drive:
    the carrier is read from the logged voltages, the angle is scored modulo pi."""
    tr = closed_loop("hfi-rotating")["0 -> 60 -> -60 r/min, 5 N m"]
    u = np.asarray(abc_to_alpha_beta(tr.u_abc))
    i = np.asarray(abc_to_alpha_beta(tr.i_abc))
    keep = slice(1000, 5000)  # a log that starts mid-run: the carrier's phase is not the log's zero
    cols = {"time": np.asarray(tr.t)[keep], "u_alpha": u[keep, 0], "u_beta": u[keep, 1]}
    cols |= {"i_alpha": i[keep, 0], "i_beta": i[keep, 1], "theta_e": np.asarray(tr.theta_e)[keep]}
    write_csv_atomic(tmp_path / "log.csv", cols)
    est = make_observer("hfi-rotating", MOTOR, TS)
    argv = ["observe", str(tmp_path / "log.csv"), "--motor", "book_salient", "--observer", "hfi-rotating"]
    argv += ["--hf-voltage", f"{float(est.hf_voltage)!r}", "--hf-frequency", "1000"]
    rc = main([*argv, "--out", str(tmp_path / "out"), "--truth-columns", "theta_e", "--no-figures"])
    assert rc == 0
    summary = json.loads((tmp_path / "out" / "observe.json").read_text())
    assert summary["angle_modulo_pi"] is True
    assert summary["errors"]["angle_rms_deg"] < LIMIT_RMS_DEG
    theta = np.loadtxt(tmp_path / "out" / "estimate.csv", delimiter=",", skiprows=1)[:, 1]
    assert theta.min() >= -math.pi / 2 and theta.max() < math.pi / 2
    # refusals: pulsating offline, HF flags on a chapter 5 observer
    assert main(["observe", str(tmp_path / "log.csv"), "--motor", "book_salient", "--observer",
                 "hfi-pulsating", "--out", str(tmp_path / "p")]) == 2  # fmt: skip
    assert main(["observe", str(tmp_path / "log.csv"), "--motor", "book_salient", "--observer", "smo",
                 "--hf-voltage", "30", "--out", str(tmp_path / "s")]) == 2  # fmt: skip
    assert not (tmp_path / "p").exists() and not (tmp_path / "s").exists()


@pytest.mark.parametrize("method", METHODS)
def test_refusals(method):
    with pytest.raises(ParameterError, match="salient"):
        make_observer(method, presets.book_motor(), TS)
    with pytest.raises(ParameterError, match="Nyquist"):
        make_observer(method, MOTOR, TS, hf_frequency=3000.0)
    with pytest.raises(ParameterError, match="hf_frequency"):
        make_observer(method, MOTOR, TS, hf_frequency=-1.0)


@pytest.mark.slow
def test_carrier_delay_bookkeeping_without_computational_delay():
    """Without the computational delay the held carrier's flux lags its command by half a period, not 1.5
    (hfi_signal docstring): ``with_observer`` sets ``delay_periods = 0.5`` and the rotating method is
    unbiased; told 1.5 instead, its image of 2 th is off by one carrier step ``w_h Ts`` (36 degrees at
    1 kHz, 10 kHz), an angle bias of ``-w_h Ts / 2`` = -18 degrees, as the derivation predicts."""
    sc = Scenario(duration_s=0.15, speed_ref=Profile.constant(0.0), load_torque=Profile.constant(2.0))
    bias = {}
    for opts in ({}, {"delay_periods": 1.5}):
        drive = presets.sensorless_drive(
            "hfi-rotating", MOTOR, computation_delay=False, observer_options=opts
        )
        tr = simulate(drive, sc, initial_state=drive.init(theta_e=0.5))
        e = np.degrees(np.asarray(angle_error_modulo_pi(tr.theta_e_est, tr.theta_e)))
        bias[drive.estimator.delay_periods] = float(np.mean(e[np.asarray(tr.t) >= 0.1]))
    w_h = float(make_observer("hfi-rotating", MOTOR, TS).hf_omega)
    assert abs(bias[0.5]) < 0.5, bias
    assert bias[1.5] == pytest.approx(-math.degrees(0.5 * w_h * TS), abs=1.0), bias
