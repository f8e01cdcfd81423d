"""MTPA from a flux map (pmsmjax/controllers/flux_map_loci.py, flux_map_references.py) against
independent references:

- on the preset saturated-ipm map, every table point's current is within 0.5 % of the least current that
  gives its torque, found by a dense grid search over current magnitude and angle on the analytic model the
  map was sampled from (its CSV header), for motoring and generating;
- on a map sampled from a linear salient motor the JAX reference and its derivative in i_q agree with the
  closed form of pmsmjax/controllers/mtpa.py;
- the MTPV locus on the cross-saturated analytic map of tests/machines/test_flux_map.py gives, at each
  point's flux magnitude, the most torque a dense grid search over currents finds within that flux;
- a map whose torque does not rise along the locus is refused in one line;
- the table's search, run on all magnitudes at once in NumPy, gives SciPy's scalar bounded search on each
  magnitude to the bit (and the array search SciPy's on smooth, kinked, flat and cut-short problems).
"""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from machines.test_flux_map import P_N, analytic_grid, psi_analytic
from scipy.optimize import minimize_scalar

from pmsmjax.controllers.flux_map_loci import (
    _SCAN_ANGLES,
    MapTorque,
    _best_angles,
    _bounded_minimum,
    mtpa_table,
    mtpv_table,
)
from pmsmjax.controllers.flux_map_references import flux_map_mtpa
from pmsmjax.controllers.mtpa import mtpa_id_from_iq
from pmsmjax.io.drive_files import preset_path
from pmsmjax.io.flux_map_files import read_flux_map
from pmsmjax.machines.flux_map import FluxMapGrid
from pmsmjax.presets.three_phase import book_motor
from pmsmjax.spec.validation import ParameterError

POLE_PAIRS = 4  # the saturated-ipm drive file's
MAX_CURRENT = 25.0  # A, its max_current_a

# The co-energy the preset map was sampled from (saturated_ipm_map.csv's header), written out here:
# W' = psi_m i_d + L_d i_d^2/2 + L_ql i_q^2/2 + L_mq s^2 ln cosh(r/s), r = sqrt(s0^2 + i_q^2 + (c i_d)^2).
A = dict(psi_m=0.1, L_d=3e-3, L_ql=2.5e-3, L_mq=10e-3, s=4.0, s0=1.0, c=0.5)


def psi_preset(i_d, i_q):
    r = np.sqrt(A["s0"] ** 2 + i_q**2 + (A["c"] * i_d) ** 2)
    g = A["L_mq"] * A["s"] * np.tanh(r / A["s"]) / r
    return A["psi_m"] + A["L_d"] * i_d + g * A["c"] ** 2 * i_d, A["L_ql"] * i_q + g * i_q


def torque_preset(i_d, i_q):
    psi_d, psi_q = psi_preset(i_d, i_q)
    return 1.5 * POLE_PAIRS * (psi_d * i_q - psi_q * i_d)


def brute_force_least_current(torques, max_current):
    """Least |i| giving each torque (N m, either sign): the most torque of each magnitude over a dense
    angle grid, then the magnitude whose most torque equals the demand (monotone, interpolated)."""
    magnitudes = np.linspace(0.0, max_current, 2601)
    beta = np.linspace(0.0, np.pi, 4001)
    mag, B = np.meshgrid(magnitudes, beta, indexing="ij")
    out = np.empty(len(torques))
    for sign in (1.0, -1.0):
        best = (sign * torque_preset(mag * np.cos(B), sign * mag * np.sin(B))).max(axis=1)
        assert np.all(np.diff(best) > 0)
        pick = np.sign(torques) == sign
        out[pick] = np.interp(np.abs(torques[pick]), best, magnitudes)
    return out


@pytest.fixture(scope="module")
def preset_grid():
    return read_flux_map(preset_path("saturated-ipm").parent / "saturated_ipm_map.csv")


def test_preset_map_really_is_the_analytic_model(preset_grid):
    D, Q = np.meshgrid(preset_grid.i_d, preset_grid.i_q, indexing="ij")
    psi_d, psi_q = psi_preset(D, Q)
    assert np.max(np.abs(psi_d - preset_grid.psi_d)) < 1e-8
    assert np.max(np.abs(psi_q - preset_grid.psi_q)) < 1e-8


def test_mtpa_table_is_the_least_current_for_each_torque(preset_grid):
    table = mtpa_table(preset_grid, POLE_PAIRS, MAX_CURRENT)
    on = table.current > 1.0  # below 1 A the relative error of a near-zero current says little
    # the torque each table point really gives (analytic model), and the least current for that torque
    torques = torque_preset(table.i_d[on], table.i_q[on])
    assert np.sum(torques > 0) > 20 and np.sum(torques < 0) > 20
    least = brute_force_least_current(torques, 1.05 * MAX_CURRENT)
    error = table.current[on] / least - 1.0
    # Required: within 0.5 %. The table is on the map's interpolant (1.5 A grid), the reference on the exact
    # model; the torque is stationary along the locus, so the map's error moves the current only at second
    # order (measured worst 2e-7; the reference's own resolution is about 1e-7).
    assert np.max(np.abs(error)) < 2e-6
    # saturation moves the locus: at 25 A the linear model at the rated point puts i_d elsewhere
    assert table.i_d[-1] < -3.0


def linear_salient_grid(n=9, span=40.0):
    motor = book_motor(salient=True)
    axis = np.linspace(-span, span, n)
    D, Q = np.meshgrid(axis, axis, indexing="ij")
    grid = FluxMapGrid(axis, axis, float(motor.L_d) * D + float(motor.psi_f), float(motor.L_q) * Q)
    return motor, grid


def test_linear_map_gives_the_closed_form_and_its_derivative():
    motor, grid = linear_salient_grid()
    block = flux_map_mtpa(grid, int(motor.pole_pairs), 30.0)
    i_q = jnp.linspace(-25.0, 25.0, 51)  # the table reaches |i_q| = 25.8 A at 30 A
    got = jax.vmap(block.locus)(i_q)
    want = mtpa_id_from_iq(motor, i_q)
    assert (
        float(jnp.max(jnp.abs(got - want))) < 1e-4
    )  # A, of up to 15 A (measured 3.7e-5, next to the origin)
    slope = jax.vmap(jax.grad(block.locus))(i_q)
    slope_want = jax.vmap(jax.grad(lambda x: mtpa_id_from_iq(motor, x)))(i_q)
    assert (
        float(jnp.max(jnp.abs(slope - slope_want))) < 6e-3
    )  # A/A, of up to 0.88 (measured 4.6e-3: PCHIP slopes)


def test_block_reads_last_periods_iq():
    motor, grid = linear_salient_grid()
    block = flux_map_mtpa(grid, int(motor.pole_pairs), 30.0)
    _, i_d = block.step(block.init(jnp.float64), 0.0, 12.0, 100.0, None, 30.0)
    assert abs(float(i_d) - float(mtpa_id_from_iq(motor, 12.0))) < 1e-5


def test_a_map_with_reversed_q_flux_is_refused():
    motor, grid = linear_salient_grid()
    # magnets reversed: motoring i_q gives negative torque along the "locus"
    flipped = FluxMapGrid(grid.i_d, grid.i_q, grid.psi_d - 2 * float(motor.psi_f), grid.psi_q, source="m.csv")
    with pytest.raises(ParameterError, match="m.csv") as err:
        mtpa_table(flipped, 4, 30.0)
    assert "\n" not in str(err.value)


def test_mtpv_is_the_most_torque_per_flux():
    grid = analytic_grid(41)  # +-40 A; its MTPV lies inside the grid for i_q up to about 24 A
    mtpa = mtpa_table(grid, P_N, 40.0)
    motoring = mtpa.i_q > 0
    mtpv = mtpv_table(grid, P_N, mtpa.i_q[motoring], mtpa.i_d[motoring])
    assert np.sum(mtpv.inside) > 40
    i_d, i_q = mtpv.i_d[mtpv.inside], mtpv.i_q[mtpv.inside]
    psi_d, psi_q = psi_analytic(i_d, i_q)
    flux = np.hypot(psi_d, psi_q)
    torque = 1.5 * P_N * (psi_d * i_q - psi_q * i_d)
    # brute force: the most torque of any current (0.02 A grid) whose flux is at most each point's
    D, Q = np.meshgrid(np.linspace(-40.0, 0.0, 2001), np.linspace(0.0, 30.0, 1501), indexing="ij")
    grid_psi_d, grid_psi_q = psi_analytic(D, Q)
    grid_flux = np.hypot(grid_psi_d, grid_psi_q).ravel()
    grid_torque = (1.5 * P_N * (grid_psi_d * Q - grid_psi_q * D)).ravel()
    order = np.argsort(grid_flux)
    most = np.maximum.accumulate(grid_torque[order])[np.searchsorted(grid_flux[order], flux, "right") - 1]
    ratio = torque / most - 1.0
    big = flux > 0.05  # Wb: below, the brute-force grid's flux resolution (about 2e-4 Wb) dominates
    # a point off MTPV would give less torque than the search (ratio < 0); the search's own resolution
    # lets it miss by a little (ratio > 0): measured up to 7.6e-4
    assert np.min(ratio[big]) > -1e-5
    assert np.max(ratio[big]) < 1e-3


def scipy_best_angle(model, current, sign):
    """The table's search on one magnitude as SciPy runs it: the scan, then minimize_scalar(bounded)."""

    def negative(beta):
        return -sign * model.torque(current * math.cos(beta), sign * current * math.sin(beta))

    betas = np.linspace(0.0, math.pi, _SCAN_ANGLES + 1)[1:-1]
    k = int(np.argmin([negative(b) for b in betas]))
    step = betas[1] - betas[0]
    bounds = (max(betas[k] - step, 1e-9), min(betas[k] + step, math.pi - 1e-9))
    return minimize_scalar(negative, bounds=bounds, method="bounded", options={"xatol": 1e-10}).x


@pytest.mark.parametrize("which", ["preset", "analytic"])
def test_array_search_is_scipys_search_on_each_magnitude(which, preset_grid):
    grid, pole_pairs = (preset_grid, POLE_PAIRS) if which == "preset" else (analytic_grid(9), P_N)
    model = MapTorque(grid, pole_pairs)
    currents = np.concatenate([np.linspace(0.0, 42.0, 22)[1:]] * 2)  # beyond the grid's corner too
    signs = np.repeat([1.0, -1.0], 21)
    got = _best_angles(model, currents, signs)
    want = [scipy_best_angle(model, c, s) for c, s in zip(currents, signs, strict=True)]
    assert np.array_equal(got, want)


@pytest.mark.parametrize(
    "f",
    [
        lambda x, c: (x - c) * (x - c),  # parabolic steps
        lambda x, c: np.abs(x - c) + 0.1 * np.abs(x - 2.0 * c),  # kinks: golden sections
        lambda x, c: np.zeros_like(x) + 0.0 * c,  # flat: every comparison a tie
        lambda x, c: ((x - c) * (x - c) - 0.5) * ((x - c) * (x - c) - 0.5) + 0.1 * x,  # two minima
    ],
)
@pytest.mark.parametrize("maxfun", [500, 6])
def test_array_bounded_search_is_scipys(f, maxfun):
    rng = np.random.default_rng(3)
    c = rng.uniform(-1.0, 3.0, 40)
    lo, hi = rng.uniform(-2.0, 0.5, 40), rng.uniform(0.6, 4.0, 40)
    got = _bounded_minimum(lambda x, lanes: f(x, c[lanes]), lo, hi, xatol=1e-10, maxfun=maxfun)
    for k in range(c.size):
        options = {"xatol": 1e-10, "maxiter": maxfun}
        want = minimize_scalar(
            lambda x, k=k: float(f(np.float64(x), c[k])),
            bounds=(lo[k], hi[k]),
            method="bounded",
            options=options,
        )
        assert got[k] == want.x, k
