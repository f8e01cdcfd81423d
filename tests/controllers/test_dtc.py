"""Direct torque control (the book, ch. 4): the flux observer, switching-table DTC and sliding-mode DTC.

What each test compares with (never the code's own earlier output):

- the switching table and sectors: a table typed in from the book (vector names per sector and comparator
  state) and the vectors' angles from the Clarke transform in NumPy;
- the comparators: their laws, case by case;
- the flux and torque estimates: the plant's own flux (the alpha-beta machine's flux equation) and torque
  at the sampling instants; the voltage model re-integrated in NumPy from the recorded duties and currents,
  with the right and with the wrong half-sample pairing;
- the drift remedy: the closed forms of a pure and a blended integrator under a DC voltage error and an
  initial error;
- the bands: a physical bound on one sample's change of the flux (``Ts (2/3 U_dc + R |i|)``);
- the two bridges: the same switch sequence replayed open-loop through both;
- the book scenario: reaching 1000 r/min and recovering from the 10 N m step (speed figures);
- equal switching frequency: the comparison's measured torque ripple of both methods;
- gradients: central finite differences in float64.

Operating point of the steady-state checks: the book scenario (1000 r/min step, 10 N m at 0.2 s, 0.4 s);
steady state is its last 0.1 s.
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

import pmsmjax
from pmsmjax import ParameterError, presets
from pmsmjax.analysis.speed_step_summary import speed_step_summary
from pmsmjax.cli import main
from pmsmjax.controllers import SlidingModeDTC, SwitchingTableDTC, smc_dtc_design
from pmsmjax.controllers.dtc import (
    SWITCHING_TABLE,
    VECTOR_SWITCHES,
    flux_sector,
    three_level_comparator,
    two_level_torque_comparator,
)
from pmsmjax.estimators import ExactSensor, StatorFluxObserver
from pmsmjax.frames.three_phase import abc_to_alpha_beta
from pmsmjax.inverters.switching import SwitchingBridge
from pmsmjax.jobs.equal_switching import match_switching_frequency
from pmsmjax.machines.pmsm3 import PMSMAlphaBeta
from pmsmjax.presets.control_methods import control_drive
from pmsmjax.signals import Estimate, References, Sample
from pmsmjax.simulate import period_inputs

MOTOR = presets.book_motor()
R, PSI_F, P = float(MOTOR.R), float(MOTOR.psi_f), MOTOR.pole_pairs
U_DC = presets.BOOK_DC_LINK
TS = presets.DTC_SAMPLE_PERIOD_S
SCENARIO = presets.book_scenario()

# The book's table as printed (module docstring of pmsmjax.controllers.dtc; Takahashi and Noguchi 1986):
# rows (phi, tau), columns sector 1..6.
BOOK_TABLE = {
    (1, 1): "V2 V3 V4 V5 V6 V1",
    (1, 0): "V7 V0 V7 V0 V7 V0",
    (1, -1): "V6 V1 V2 V3 V4 V5",
    (0, 1): "V3 V4 V5 V6 V1 V2",
    (0, 0): "V0 V7 V0 V7 V0 V7",
    (0, -1): "V5 V6 V1 V2 V3 V4",
}
# Leg states of the vectors, by name (a b c, upper switch on = 1).
BOOK_VECTORS = {
    "V0": "000",
    "V1": "100",
    "V2": "110",
    "V3": "010",
    "V4": "011",
    "V5": "001",
    "V6": "101",
    "V7": "111",
}


# --- the table, the sectors and the comparators ---------------------------------------------------------


def test_vector_states_point_where_the_book_says():
    """V_k (k = 1..6) at (k - 1) 60 deg with length 2/3 U_dc; V0 and V7 zero (Clarke in NumPy)."""
    for k, name in enumerate(BOOK_VECTORS):
        legs = np.array([int(c) for c in BOOK_VECTORS[name]], float)
        np.testing.assert_array_equal(VECTOR_SWITCHES[k], legs)
        u = U_DC * (legs - legs.mean())
        alpha, beta = (2 * u[0] - u[1] - u[2]) / 3, (u[1] - u[2]) / math.sqrt(3)
        if name in ("V0", "V7"):
            assert abs(alpha) < 1e-12 and abs(beta) < 1e-12
        else:
            assert math.hypot(alpha, beta) == pytest.approx(2 / 3 * U_DC, rel=1e-12)
            assert math.degrees(math.atan2(beta, alpha)) % 360 == pytest.approx((k - 1) * 60.0, abs=1e-9)


def test_table_matches_the_book_in_every_sector_and_comparator_state():
    for (phi, tau), row in BOOK_TABLE.items():
        for sector, name in enumerate(row.split()):
            assert SWITCHING_TABLE[phi, tau + 1, sector] == int(name[1]), (phi, tau, sector + 1)


def test_sectors_span_60_degrees_with_sector_1_from_minus_30_to_30():
    """Sector k is the one whose centre (k - 1) 60 deg is nearest the flux angle (sector 1: -30..30 deg)."""
    centres = np.radians(60.0 * np.arange(6))
    for a in np.arange(-179.5, 180.0, 1.0):
        rad = math.radians(a)
        distance = np.abs(np.angle(np.exp(1j * (rad - centres))))
        psi = 0.18 * jnp.array([math.cos(rad), math.sin(rad)])
        assert int(flux_sector(psi)) == int(np.argmin(distance)), a
    for degrees, sector in ((29.9, 0), (30.1, 1), (-29.9, 0), (-30.1, 5), (89.9, 1), (90.1, 2)):
        rad = math.radians(degrees)
        assert int(flux_sector(jnp.array([math.cos(rad), math.sin(rad)]))) == sector, degrees


def test_comparator_laws_case_by_case():
    h = 1.0
    # (error, previous) -> three-level output: thresholds at +-h/2, back to 0 where the error crosses 0.
    three = {
        (0.6, 0.0): 1,
        (0.6, -1.0): 1,
        (-0.6, 0.0): -1,
        (-0.6, 1.0): -1,
        (0.3, 1.0): 1,
        (-0.1, 1.0): 0,
        (0.0, 1.0): 0,
        (0.1, -1.0): 0,
        (-0.3, -1.0): -1,
        (0.4, 0.0): 0,
        (-0.4, 0.0): 0,
    }
    for (e, prev), out in three.items():
        assert float(three_level_comparator(jnp.asarray(e), h, jnp.asarray(prev))) == out, (e, prev)
    two = {(0.6, -1.0): 1, (-0.6, 1.0): -1, (0.2, -1.0): -1, (-0.2, 1.0): 1}
    for (e, prev), out in two.items():
        assert float(two_level_torque_comparator(jnp.asarray(e), h, jnp.asarray(prev))) == out, (e, prev)


def _controller_step(controller, sector, e_psi, e_t, phi_prev, tau_prev):
    """One step of ``controller`` in torque mode with the flux at the centre of ``sector`` (0..5) and the
    given flux and torque errors; returns the commanded leg states."""
    angle = math.radians(60.0 * sector)
    magnitude = PSI_F - e_psi
    psi = magnitude * jnp.array([math.cos(angle), math.sin(angle)])
    iq_ref = 5.0
    torque = float(MOTOR.torque_constant) * iq_ref - e_t
    zero2 = jnp.zeros(2)
    sample = Sample(jnp.zeros(3), zero2, jnp.asarray(U_DC), zero2, jnp.asarray(0.0), jnp.asarray(100.0))
    estimate = Estimate(jnp.asarray(0.0), jnp.asarray(100.0), None, psi, jnp.asarray(torque))
    state = controller.init(jnp.float64)
    state = eqx.tree_at(lambda s: (s.phi, s.tau), state, (jnp.asarray(phi_prev), jnp.asarray(tau_prev)))
    refs = References(jnp.asarray(0.0), jnp.asarray(0.0), jnp.asarray(iq_ref))
    _, out = controller.step(state, sample, estimate, refs, TS, U_DC / math.sqrt(3), False)
    return "".join(str(int(x)) for x in np.asarray(out.command))


def test_controller_commands_the_book_vector_in_every_sector_and_comparator_state():
    """The whole chain (comparators, sector, table, leg states) for every sector x (phi, tau)."""
    controller = SwitchingTableDTC(MOTOR, 1.0, 0.01, 15.0, mode="torque")
    # Errors that put the comparators in each state: beyond the bands, or inside them with the state held.
    flux_errors = {1: 0.02, 0: -0.02}
    torque_cases = {1: (0.8, 0.0), -1: (-0.8, 0.0), 0: (0.2, 0.0)}  # (error, previous tau)
    for sector in range(6):
        for (phi, tau), row in BOOK_TABLE.items():
            e_t, tau_prev = torque_cases[tau]
            legs = _controller_step(controller, sector, flux_errors[phi], e_t, 0.0, tau_prev)
            assert legs == BOOK_VECTORS[row.split()[sector]], (sector + 1, phi, tau)


# --- closed-loop runs shared by the tests below -----------------------------------------------------------


@functools.cache
def table_run(**options):
    """The table-DTC preset through the book scenario, keeping per sample: the plant state at the sample,
    the estimator's flux and torque, the controller's torque reference and comparator states, the duties."""
    drive = presets.dtc_drive(**options)
    xs = period_inputs(SCENARIO, drive.Ts)

    @jax.jit
    def run(drive, xs):
        def body(s, x):
            s_next, rec = drive.step(s, x)
            c = s_next.controller
            return s_next, (s.machine, s_next.estimator.psi_ab, c.torque_ref, c.phi, c.tau, rec.duties)

        return jax.lax.scan(body, drive.init(), xs)[1]

    ms, psi, torque_ref, phi, tau, duties = jax.device_get(run(drive, xs))
    phi = np.asarray(phi)
    i_ab = np.asarray(jax.vmap(drive.machine.stationary_currents)(ms))
    psi = np.asarray(psi)
    torque_est = 1.5 * P * (psi[:, 0] * i_ab[:, 1] - psi[:, 1] * i_ab[:, 0])
    return {
        "drive": drive,
        "machine": ms,
        "i_ab": i_ab,
        "psi": psi,
        "torque_est": torque_est,
        "torque_ref": np.asarray(torque_ref),
        "tau": np.asarray(tau),
        "phi": phi,
        "duties": np.asarray(duties),
    }


def steady(n):
    return slice(int(0.75 * n), n)


def plant_flux_and_torque(ms):
    """The plant's stator flux ``(N, 2)`` Wb and torque ``(N,)`` N m from the alpha-beta model's own flux
    equation ``psi = L(theta) i + psi_f [cos, sin]`` (independent of the dq current model)."""
    ab = PMSMAlphaBeta(MOTOR)
    i_dq = jnp.asarray(ms.currents)
    theta = jnp.asarray(ms.theta_e)
    i_ab = jax.vmap(ab.currents_from_dq)(i_dq, theta)
    psi = jax.vmap(ab.flux)(i_ab, theta)
    torque = jax.vmap(ab.torque)(i_ab, theta)
    return np.asarray(psi), np.asarray(torque)


# --- flux and torque estimation -----------------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("crossover", [presets.FLUX_OBSERVER_CROSSOVER, 0.0])
def test_estimated_flux_and_torque_match_the_plant_within_1_percent(crossover):
    """Measured (float64): |psi| within 8e-7 relative and T within 8e-6 N m for both the blend and the
    pure voltage model; the claim is 1 %."""
    run = table_run(crossover_rad_s=crossover)
    psi_true, torque_true = plant_flux_and_torque(run["machine"])
    window = steady(len(torque_true))
    mag_est = np.hypot(run["psi"][:, 0], run["psi"][:, 1])[window]
    mag_true = np.hypot(psi_true[:, 0], psi_true[:, 1])[window]
    assert np.max(np.abs(mag_est / mag_true - 1.0)) < 0.01
    torque_scale = np.mean(np.abs(torque_true[window]))  # 10.9 N m: the loaded torque
    assert np.max(np.abs(run["torque_est"][window] - torque_true[window])) < 0.01 * torque_scale


def test_half_sample_bookkeeping_matters():
    """The voltage model re-integrated in NumPy from the recorded duties and sampled currents: pairing the
    flux at t_k with the voltage applied over [t_{k-1}, t_k) reproduces the observer; pairing it with the
    voltage applied over [t_k, t_{k+1}) puts the flux one sample ahead and the torque several percent off."""
    run = table_run(crossover_rad_s=0.0)
    legs = run["duties"]
    u_ab = np.asarray(abc_to_alpha_beta(U_DC * (legs - legs.mean(axis=1, keepdims=True))))
    i_ab = run["i_ab"]
    n = len(i_ab)

    def integrate(shift):
        psi = np.empty((n, 2))
        psi[0] = run["psi"][0]
        for k in range(1, n):
            psi[k] = psi[k - 1] + TS * (u_ab[k - 1 + shift] - R * 0.5 * (i_ab[k - 1] + i_ab[k]))
        return psi

    _, torque_true = plant_flux_and_torque(run["machine"])
    window = steady(n)
    scale = np.mean(np.abs(torque_true[window]))
    for shift, ok in ((0, True), (1, False)):
        psi = integrate(shift)
        torque = 1.5 * P * (psi[:, 0] * i_ab[:, 1] - psi[:, 1] * i_ab[:, 0])
        error = np.max(np.abs(torque[window] - torque_true[window])) / scale
        if ok:
            np.testing.assert_allclose(psi, run["psi"], rtol=0, atol=1e-9)
            assert error < 0.01
        else:
            assert error > 0.03, error


def _observer_run(crossover, psi0, u_ab, n=2000, ts=TS):
    """The observer alone at standstill (zero current, rotor at 0) under a constant voltage ``u_ab``,
    from the initial flux estimate ``psi0``: its flux estimates ``(n, 2)``, Wb."""
    observer = StatorFluxObserver(MOTOR, crossover, ExactSensor())
    zero2 = jnp.zeros(2)
    sample = Sample(
        jnp.zeros(3), zero2, jnp.asarray(U_DC), jnp.asarray(u_ab), jnp.asarray(0.0), jnp.asarray(0.0)
    )
    state = eqx.tree_at(lambda s: s.psi_ab, observer.init(sample), jnp.asarray(psi0))

    def body(s, _):
        s, est = observer.step(s, sample, ts)
        return s, est.psi_ab

    return np.asarray(jax.lax.scan(body, state, None, length=n)[1])


def test_pure_integrator_drifts_and_the_blend_bounds_the_error():
    """A 0.5 V DC error (e.g. 0.5 A of current-sensor offset times R) and a 20 mWb initial error, at
    standstill where the true flux is psi_f on the alpha axis. Pure integrator: the offset ramps as
    ``d t`` and the initial error never decays. Blend at w_c: the DC error settles at
    ``a Ts d/(1 - a)`` (~ d/w_c) and the initial error decays as ``a^k = exp(-w_c k Ts)``."""
    w_c, n = presets.FLUX_OBSERVER_CROSSOVER, 2000  # 50 ms: 2.5 time constants
    truth = np.array([PSI_F, 0.0])
    d = np.array([0.5, 0.0])
    k = np.arange(1, n + 1)
    pure = _observer_run(0.0, truth, d, n)
    np.testing.assert_allclose(pure[:, 0] - PSI_F, k * TS * d[0], rtol=1e-9, atol=1e-15)
    a = math.exp(-w_c * TS)
    blend = _observer_run(w_c, truth, d, n)
    closed_form = a * TS * d[0] * (1 - a**k) / (1 - a)
    np.testing.assert_allclose(blend[:, 0] - PSI_F, closed_form, rtol=1e-9, atol=1e-15)
    assert blend[-1, 0] - PSI_F < d[0] / w_c  # bounded by d / w_c (10 mWb) while the ramp grows on

    offset = np.array([0.0, 0.02])
    pure = _observer_run(0.0, truth + offset, np.zeros(2), n)
    np.testing.assert_allclose(pure[:, 1], offset[1], rtol=1e-12)
    blend = _observer_run(w_c, truth + offset, np.zeros(2), n)
    np.testing.assert_allclose(blend[:, 1], offset[1] * a**k, rtol=1e-9, atol=1e-15)


# --- bands, book scenario, bridges --------------------------------------------------------------------------


def test_table_dtc_keeps_flux_and_torque_in_their_bands_widened_by_one_sample():
    """Steady state under 10 N m (last 0.1 s, 4000 samples).

    Flux: ``|psi* - |psi|| <= h_psi/2 + delta_psi`` with ``delta_psi = Ts (2/3 U_dc + R max|i|)``, the most
    any vector moves the flux magnitude in one sample (5.5 mWb here; measured excess 4.3 mWb, mostly while
    zero vectors leave the flux uncontrolled).

    Torque: at every sample, ``|T* - T| <= h_T/2 + |change of T* - T over that sample|`` (it left the band
    within the last sample, or not at all), except right after ``V(k+2)`` (``phi = 0``, ``tau = +1``) in the
    first half of a sector: that vector points 150-120 deg ahead of the flux there, so its radial part
    (180-100 V) lowers the flux magnitude, and with it the torque, faster than its tangential part raises
    the load angle, and the torque keeps falling for a few samples (the six-sector table's known weakness;
    measured: 127 of 4000 samples, up to 0.70 N m beyond h_T/2). Overall ``|T* - T| <= h_T/2 + max
    one-sample change``.
    """
    run = table_run()
    controller = run["drive"].controller
    n = len(run["torque_est"])
    window = np.arange(n) >= int(0.75 * n)

    mag = np.hypot(run["psi"][:, 0], run["psi"][:, 1])
    e_psi = float(controller.flux_ref_wb) - mag
    i_max = np.max(np.hypot(run["i_ab"][:, 0], run["i_ab"][:, 1]))
    delta_psi = TS * (2.0 / 3.0 * U_DC + R * i_max)
    h_psi = float(controller.flux_band_wb)
    assert np.max(np.abs(e_psi[window])) <= h_psi / 2 + delta_psi
    assert np.max(np.abs(e_psi[window])) > h_psi / 2  # the sampling does overshoot the band

    e_t = run["torque_ref"] - run["torque_est"]
    h_t = float(controller.torque_band_nm)
    change = np.abs(np.diff(e_t, prepend=e_t[0]))
    assert np.max(np.abs(e_t[window])) <= h_t / 2 + np.max(change[window])
    angle = np.degrees(np.arctan2(run["psi"][:, 1], run["psi"][:, 0]))
    in_sector = (angle + 30.0) % 60.0 - 30.0  # -30 at the sector start, +30 at its end
    escaped = window & (np.abs(e_t) > h_t / 2 + change)
    after = np.nonzero(escaped)[0] - 1
    assert np.all(in_sector[escaped] < 0.0)
    assert np.all(run["tau"][after] == 1) and np.all(run["phi"][after] == 0)
    assert np.sum(escaped) < 0.05 * np.sum(window)


@pytest.mark.slow
@pytest.mark.parametrize(
    "name, options",
    [
        ("dtc", {}),
        ("dtc", {"torque_levels": 2}),
        ("dtc", {"computation_delay": True}),
        ("smc-dtc", {}),
        ("smc-dtc", {"switching": "sign"}),
    ],
)
def test_book_scenario_reaches_1000_rpm_and_recovers_from_the_load_step(name, options):
    """1000 r/min within 2 % by 0.2 s; after the 10 N m step back within 10 r/min of it by the end."""
    drive = control_drive(name, **options)
    trace = pmsmjax.simulate(drive, SCENARIO)
    summary = speed_step_summary(trace, load_time_s=0.2, current_limit_a=15.0)
    assert summary["rise_time_s"] < 0.06
    assert abs(summary["steady_state_error_rpm"]) < 20.0
    assert 150.0 < summary["speed_dip_rpm"] < 300.0  # the speed PI's dip (FOC: 243 r/min)
    assert summary["recovery_time_s"] is not None and summary["recovery_time_s"] < 0.19
    assert abs(summary["final_speed_rpm"] - 1000.0) < 10.0


@pytest.mark.slow
def test_both_bridges_apply_held_switch_states_alike():
    """The table's switch sequence (duties 0/1) replayed open-loop through the averaged and the
    switching-resolved bridge from the same state: a leg held for a whole sample has no edge inside it, so
    both apply the same held voltage (equal to 1e-12 V) and follow the machine to within their RK4 error
    against a 64-sub-step reference (measured 1.0e-8 A for the averaged bridge's one 25 us step, 1.3e-9 A
    for the switching bridge, which cuts the period at its middle; the averaged bridge at two sub-steps
    6.5e-10 A: fourth order). The averaged replay also reproduces the closed-loop run."""
    run = table_run()
    drive = run["drive"]
    duties = jnp.asarray(run["duties"][4000:5000])
    start = jax.tree.map(lambda x: x[4000], run["machine"])
    load = jnp.asarray(0.0)  # 0.1-0.125 s: before the load step

    def replay(bridge, n_substeps):
        def body(s, d):
            s, u = bridge.advance(drive.machine, s, d, load, drive.Ts, n_substeps)
            return s, (s.currents, u)

        currents, u = jax.lax.scan(body, start, duties)[1]
        return np.asarray(currents), np.asarray(u)

    reference, u_ref = replay(drive.bridge, 64)
    i_avg, u_avg = replay(drive.bridge, 1)
    i_avg2, _ = replay(drive.bridge, 2)
    i_sw, u_sw = replay(SwitchingBridge(U_DC), 1)
    np.testing.assert_allclose(u_sw, u_avg, rtol=0, atol=1e-12)
    np.testing.assert_allclose(u_ref, u_avg, rtol=0, atol=1e-12)
    error = lambda i: np.max(np.abs(i - reference))
    assert error(i_avg) < 5e-8 and error(i_sw) <= error(i_avg)
    assert error(i_avg2) < error(i_avg) / 8.0  # RK4 is fourth order: 16x per halving
    np.testing.assert_allclose(i_avg, run["machine"].currents[4001:5001], rtol=0, atol=1e-12)


# --- comparison at equal switching frequency, CLI -----------------------------------------------------------


@pytest.fixture(scope="module")
def compared(tmp_path_factory):
    out = tmp_path_factory.mktemp("compare_dtc")
    assert main(["compare", "--control", "dtc,smc-dtc", "--equal-switching", "--out", str(out)]) == 0
    return out, json.loads((out / "compare.json").read_text())


@pytest.mark.slow
def test_smc_dtc_has_lower_torque_ripple_than_table_dtc_at_equal_switching_frequency(compared):
    """SVPWM at 10 kHz against the table with its bands scaled to the same mean switching frequency
    (measured: 0.14 N m RMS against 0.38; at the book bands the table switches at 4.3 kHz with 0.34)."""
    out, data = compared
    entries = data["controllers"]
    assert list(entries) == ["dtc", "dtc@10kHz", "smc-dtc"]
    smc, matched, book = entries["smc-dtc"], entries["dtc@10kHz"], entries["dtc"]
    assert smc["switching_frequency_hz"] == pytest.approx(1e4, rel=1e-12)
    assert matched["switching_frequency_hz"] == pytest.approx(1e4, rel=0.01)
    assert matched["torque_band_nm"] == pytest.approx(matched["band_factor"] * book["torque_band_nm"])
    assert book["switching_frequency_hz"] < 0.7e4  # the book bands switch less
    for key in ("torque_ripple_nm", "torque_ripple_pp_nm", "flux_ripple_wb", "current_thd_pct"):
        assert smc[key] < matched[key], key
    for entry in entries.values():
        assert entry["mean_torque_nm"] == pytest.approx(10.0 + 0.008 * 104.72, rel=0.02)
        assert abs(entry["final_speed_rpm"] - 1000.0) < 10.0
    for name in ("compare_speed.png", "compare_ripple.png", "compare_flux.png"):
        assert (out / name).read_bytes()[:4] == b"\x89PNG"


def test_band_search_meets_a_target_and_refuses_an_impossible_one():
    drive = presets.dtc_drive()
    scenario = presets.book_scenario(duration_s=0.25, load_time_s=0.1)
    result = match_switching_frequency(drive, scenario, 6e3, 1200)
    assert result["converged"] and result["switching_frequency_hz"] == pytest.approx(6e3, rel=0.01)
    # Wider bands switch less: the search's runs are ordered that way.
    runs = sorted(result["runs"])
    assert runs[0][1] > runs[-1][1]
    with pytest.raises(ParameterError, match="most a leg"):
        match_switching_frequency(drive, scenario, 25e3, 1200)


@pytest.mark.slow
@pytest.mark.parametrize("control", ["dtc", "smc-dtc"])
def test_demo_runs_each_dtc_variant(control, tmp_path):
    out = tmp_path / control
    args = ["--duration-s", "0.15", "--load-time-s", "0.1", "--load-nm", "0", "--no-figures"]
    assert main(["demo", "--control", control, "--out", str(out), *args]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["drive"]["control"] == control
    assert abs(summary["metrics"]["final_speed_rpm"] - 1000.0) < 5.0


def test_demo_dtc_flags_reach_the_preset_and_others_are_refused(tmp_path, capsys):
    from pmsmjax.cli.demo import options_from_flags
    from pmsmjax.presets.control_methods import control_drive

    class Args:
        machine, control = "three-phase", "dtc"
        torque_band_nm, flux_band_wb, sample_period_us = 0.5, 0.004, 40.0

    drive = control_drive("dtc", MOTOR, **options_from_flags(Args(), None))
    assert drive.Ts == pytest.approx(40e-6)
    assert float(drive.controller.torque_band_nm) == 0.5 and float(drive.controller.flux_band_wb) == 0.004
    assert main(["demo", "--control", "smc-dtc", "--torque-band-nm", "1", "--out", str(tmp_path / "x")]) == 2
    assert "--torque-band-nm does not apply to --control smc-dtc" in capsys.readouterr().err


# --- tuning and gradients -----------------------------------------------------------------------------------


@pytest.mark.slow
def test_gradient_of_the_smc_dtc_objective_matches_central_differences():
    """The tuning objective (speed ITAE + 0.1 x torque ripple) of the tanh SMC-DTC on two short batch
    scenarios, against its four gains in log space (float64)."""
    from tuning.autotune.objectives import ObjectiveWeights, batch_cost
    from tuning.autotune.scenario_batches import make_batch
    from tuning.parameters import LogParameterisation

    batch = make_batch(2, 3, duration_s=(0.02, 0.03), speed_rpm=(200.0, 400.0))
    drive = presets.smc_dtc_drive(switching="tanh", n_substeps=1)
    param = LogParameterisation(drive, ("smc_dtc",))
    weights = ObjectiveWeights(torque_ripple=0.1)
    cost = jax.jit(lambda th: batch_cost(param.apply(drive, th), batch, weights)[0])
    theta = jnp.array([0.1, -0.2, 0.15, 0.3])
    # log-space step 1e-5 (step_floor 1: the factors are of order 1)
    r = check_gradient(cost, theta, rel_step=1e-5, rtol=1e-4, atol=1e-10, labels=param.names)
    assert np.all(np.abs(r.grad) > 1e-9)  # every gain moves the objective


@pytest.mark.slow
def test_tune_smc_dtc_tunes_the_tanh_surrogate_and_reports_the_saturation_law(tmp_path):
    out = tmp_path / "tune"
    args = ["tune", "--control", "smc-dtc", "--out", str(out), "--train", "2", "--heldout", "2"]
    more = ["--iterations", "2", "--duration-s", "0.04", "0.05", "--eval-substeps", "1", "--no-progress"]
    assert main([*args, *more]) == 0
    data = json.loads((out / "result.json").read_text())
    assert data["control"] == "smc-dtc"
    assert data["surrogate"]["options"] == {"switching": "tanh"}
    assert data["weights"]["torque_ripple"] > 0
    for name in ("controller.torque_gain_v", "controller.flux_boundary_wb", "controller.speed.kp"):
        assert name in data["gains"]["after"]
    for when in ("after", "after_surrogate"):
        assert np.isfinite(data["heldout"][when]["itae"])
        assert np.isfinite(data["heldout"][when]["torque_ripple_nm"])


# --- validation ---------------------------------------------------------------------------------------------


def test_bad_settings_are_refused_before_compiling():
    with pytest.raises(ParameterError, match="torque_band_nm"):
        presets.dtc_drive(torque_band_nm=0.0)
    with pytest.raises(ParameterError, match="torque_levels"):
        SwitchingTableDTC(MOTOR, 1.0, 0.01, 15.0, torque_levels=4)
    with pytest.raises(ParameterError, match="crossover_rad_s"):
        StatorFluxObserver(MOTOR, -1.0)
    with pytest.raises(ParameterError, match="too fast"):
        smc_dtc_design(MOTOR, torque_bandwidth_rad_s=6000.0, Ts=1e-4)
    with pytest.raises(ParameterError, match="switching"):
        presets.smc_dtc_drive(switching="relay")
    # A DTC drive whose estimator gives no flux is refused while tracing, naming the fix.
    drive = eqx.tree_at(lambda d: d.estimator, presets.dtc_drive(), ExactSensor())
    with pytest.raises(ParameterError, match="StatorFluxObserver"):
        pmsmjax.simulate(drive, presets.book_scenario(duration_s=0.001))
    assert isinstance(presets.smc_dtc_drive().controller, SlidingModeDTC)
