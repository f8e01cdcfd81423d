"""A synchronous reluctance machine's flux map as the power-law saturation model, its few parameters fitted to
the log the gridded fit uses (``pmsmjax identify --flux-map --flux-model power-law``).

**The model** ([`pmsmjax.machines.syrm_saturation`][pmsmjax.machines.syrm_saturation]; M. Hinkkanen,
P. Pescetto, E. Mölsä, S. E. Saarakkala, G. Pellegrino, R. Bojoi, "Sensorless self-commissioning of
synchronous reluctance motors at standstill without rotor locking", IEEE Trans. Ind. Appl. 53(3), 2017,
doi:10.1109/TIA.2016.2644624): the current as a function of the flux, in this project's axes
(``x = psi_q`` the high-permeance axis, ``y = psi_d - psi_f`` the flux-barrier axis)

    i_q = (a_x0 + a_xx |x|^S + a_xy/(V+2) |x|^U |y|^(V+2)) x
    i_d = (a_y0 + a_yy |y|^T + a_xy/(U+2) |x|^(U+2) |y|^V) y - i_f

five inverse inductances (1/H and 1/(H Wb^k), all positive), four exponents and the magnets, either as an
MMF ``i_f`` (A) or as a flux ``psi_f`` (Wb) in series with the iron. Nine numbers instead of a grid's
hundreds: a log that visits few operating points, or one path, still determines them, and the map between
and beyond the visited currents is the model's, not a smoothness prior's. It is a model of a reluctance
rotor's iron; an interior-magnet machine's map (saturating bridges, the magnet's flux bending with the q
current) is not of this form, and the fit then leaves a model error the grid does not
(``docs/guides/identification.md`` has the figures).

**The residuals: the gridded fit's.** The same windows of the voltage equation in integral form, the same
end averaging, the same unweighted least squares in Wb
([`tuning.identify.flux_map_fit`][tuning.identify.flux_map_fit], whose `window_equations` prepares them),
with ``psi(i)`` at every logged current the model's flux instead of the grid interpolant's. The model gives
the current from the flux, so the flux at each logged current is its inverse: Newton's method on the
current map (a gradient of a convex co-energy near the operating region, unique inverse), its steps capped
at `NEWTON_STEP_WB`, run with the parameters held (``stop_gradient``) and followed by one Newton step that
carries them: at the converged flux that step's derivative is the implicit function theorem's
``dpsi/dtheta = -(di/dpsi)^-1 di/dtheta``, so the Jacobian is exact without differentiating the iterations.

**The solve.** Levenberg-Marquardt (``optimistix.LevenbergMarquardt``, forward-mode JAX Jacobians,
float64) over the logarithms of the five coefficients (positive by construction) and, when fitted, of
``S``, ``T``, ``U`` (``V`` stays the paper's 0: ``|y|^V`` with ``V < 0`` diverges where ``y`` crosses
zero), the magnet (linear), R (its logarithm, unless given) and the inverter voltage error (linear, its
sign's width the gridded fit's). The start: the gridded fit of the same log, then the model fitted to the
grid's measured nodes in the current domain, where it is linear in the coefficients and the MMF (a linear
least-squares solve; ``psi_f`` from the grid at zero current).

**Exponents.** By default the paper's, ``S = 5, T = 1, U = 1, V = 0``, fixed (``exponents="fitted"`` fits
S, T, U, started from the fixed-exponent fit). Measured (``benchmarks/flux_map_identification.py``): on the
reluctance machine's staircase, whose truth has the paper's exponents, fitting them finds S, T, U within
1-8 % but leaves the map's error where it was (0.027 % of the flux range against 0.020 %) and widens the
coefficients' intervals two to eight times (the exponents and coefficients trade off), one of which
(``a_y0``, 7 % off) then misses the truth; on the interior-magnet machine it lowers the model error from
0.55 % to 0.18 %, still above the grid's 0.08 %. The machine the model is for is better served by the
paper's exponents.

**The magnet** (``magnet="auto"``): both forms are fitted and the one with the smaller window residual is
kept; when its magnet's 95 % interval covers zero the log shows no magnet and the pure reluctance model
(``i_f = psi_f = 0``) is fitted instead.

**Noisy currents.** The model is evaluated at the logged, noisy currents (as the grid is): windows at a
dwell whose ends differ only by the current noise pull the incremental inductance towards zero (errors in
the variables). The end averaging of the gridded fit reduces this; on the reluctance staircase with 0.05 A
of current noise it still leaves ``a_y0`` (the small d-axis inverse inductance) 4 % high, 2-3 standard
errors, while with noise on the voltages only every coefficient is within its interval (measured). The fit
therefore extrapolates the bias away (SIMEX, simulation-extrapolation: J. R. Cook and L. A. Stefanski,
"Simulation-extrapolation estimation in parametric measurement error models", J. Amer. Statist. Assoc.
89(428), 1994, doi:10.1080/01621459.1994.10476871): it refits `SIMEX_DRAWS` times with fresh white noise of
the log's own current noise level (robust, from second differences,
[`tuning.identify.fit.noise_level`][tuning.identify.fit.noise_level]) added, so that the noise variance
doubles, and takes ``2 y - mean(y_doubled)`` in the solver's coordinates (the bias linear in the noise
variance, to first order). The added noise's own scatter enters the covariance as the factor
``1 + 1/draws`` (it is at most the fitted noise's). Measured on the staircase at seeds 2-7 (``magnet=
"flux"``): the coefficients' errors are within 1.6 standard errors but for ``a_y0`` at seed 7 (2.04: its
interval misses the truth); ``a_y0``'s errors average +1.1 standard errors (the linear extrapolation
removes most of the bias, not all).

**Intervals.** Gauss-Newton covariance at the optimum as the other fits here
([`tuning.identify.uncertainty.covariance`][tuning.identify.uncertainty.covariance]): the residual
variance from the fit, the sandwich with Newey-West lags over twice the overlap of the windows (they share
samples up to a window and its averaged ends apart), 1.96 sigma; for a coefficient fitted as a logarithm
the interval is ``exp(log value +- 1.96 sigma)``.
"""

import dataclasses
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from pmsmjax.machines.flux_map import FluxMapGrid
from pmsmjax.machines.syrm_saturation import PowerLawSaturation
from pmsmjax.spec.validation import ParameterError
from tuning.identify.fit import noise_level
from tuning.identify.flux_map_fit import (
    FluxMapFit,
    _checked_speed,
    _inverter_error_per_volt,
    fit_flux_map,
    window_equations,
)
from tuning.identify.uncertainty import covariance

__all__ = ["FluxModelFit", "fit_power_law_flux_map", "PAPER_EXPONENTS", "COEFFICIENTS", "NEWTON_STEP_WB"]

#: The exponents of Hinkkanen et al. 2017 (dimensionless).
PAPER_EXPONENTS = {"S": 5.0, "T": 1.0, "U": 1.0, "V": 0.0}
#: The positive coefficients, their units.
COEFFICIENTS = {
    "a_x0": "1/H",
    "a_xx": "1/(H Wb^S)",
    "a_y0": "1/H",
    "a_yy": "1/(H Wb^T)",
    "a_xy": "1/(H Wb^(U+V+2))",
}
#: Largest Newton step of the inverse, Wb: far from the root the power law's steep branch (``|x|^5``)
#: would throw a full step past it.
NEWTON_STEP_WB = 0.05
#: Newton iterations of the inverse (the cap lets a step cover 2 Wb in 40; then quadratic convergence).
NEWTON_ITERATIONS = 60
#: Newton residual, A, beyond which an inverse counts as failed.
NEWTON_TOL_A = 1e-6
MAGNETS = ("flux", "mmf", "none")
#: Intervals of the written map per interval of the gridded fit's grid: the model is sampled finer than
#: the grid, since a sampled map is only as good as its interpolant (the reluctance machine's true map
#: sampled at 5 A and interpolated is 0.13 % of the flux range off along its ordinary operation's path, at
#: 1.25 A 0.006 %).
SAMPLING_REFINEMENT = 4
#: Levenberg-Marquardt steps at most.
MAX_STEPS = 200
#: Refits with the current noise doubled (fresh noise of the log's own level added), whose mean the
#: noisy-current bias is extrapolated from (module docstring, "Noisy currents").
SIMEX_DRAWS = 2


@dataclasses.dataclass(frozen=True)
class FluxModelFit:
    """The fitted model and its sampled map.

    - `map`: the [`FluxMapFit`][tuning.identify.flux_map_fit.FluxMapFit] that is written and used: the
      model sampled over the gridded fit's grid, `SAMPLING_REFINEMENT` times finer (a node measured where
      its nearest grid node is), the model fit's R, inverter error and window residual;
    - `model`: the [`PowerLawSaturation`][pmsmjax.machines.syrm_saturation.PowerLawSaturation];
    - `parameters`: ``{name: {"value", "stderr", "ci95", "unit", "fitted_as", "bias_removed"}}`` of every
      fitted parameter (``stderr`` of the logarithm for ``fitted_as = "log"``, relative; else in the unit) and
      ``"bias_removed"``, what the noisy-current extrapolation changed (relative for a logarithm);
    - `magnet`: ``"flux"`` (``psi_f``), ``"mmf"`` (``i_f``) or ``"none"``; `exponents`: ``"paper"`` or
      ``"fitted"``;
    - `grid_fit`: the gridded fit of the same log (the start; its residual is the comparison);
    - `residual_rms_wb`: RMS window residual, Wb; `newton_residual_a`: the largest current error of the
      flux inverse at the logged currents, A; `steps`: Levenberg-Marquardt steps of the kept fit.
    """

    map: FluxMapFit
    model: PowerLawSaturation
    parameters: dict
    magnet: str
    exponents: str
    grid_fit: FluxMapFit
    residual_rms_wb: float
    newton_residual_a: float
    steps: int


def _pow(z, e):
    """``z^e`` for ``z >= 0`` with finite derivatives at ``z = 0`` (``z^0 = 1``; JAX's own ``0^0`` has a NaN
    slope)."""
    pos = z > 0
    safe = jnp.where(pos, z, 1.0)
    return jnp.where(pos, jnp.exp(e * jnp.log(safe)), jnp.where(e == 0, 1.0, 0.0))


def _current(psi, p):
    """``(2,)`` A: the model's ``(i_d, i_q)`` at the flux ``psi (2,)`` Wb; ``p``: parameters by name."""
    y = psi[0] - p["psi_f"]
    x = psi[1]
    ax, ay = jnp.abs(x), jnp.abs(y)
    S, T, U, V = p["S"], p["T"], p["U"], p["V"]
    g_x = p["a_x0"] + p["a_xx"] * _pow(ax, S) + p["a_xy"] / (V + 2) * _pow(ax, U) * _pow(ay, V + 2)
    g_y = p["a_y0"] + p["a_yy"] * _pow(ay, T) + p["a_xy"] / (U + 2) * _pow(ax, U + 2) * _pow(ay, V)
    return jnp.stack([g_y * y - p["i_f"], g_x * x])


def _one_axis_start(c, a0, a1, k):
    """The flux of one axis alone, ``a0 z + a1 |z|^k z = c``, bounded above by both terms' own solutions."""
    return jnp.sign(c) * jnp.minimum(jnp.abs(c) / a0, (jnp.abs(c) / a1) ** (1.0 / (k + 1.0)))


def _flux_at(p, i_dq):
    """``((N, 2) Wb, (N,) A)``: the model's flux at the currents ``i_dq (N, 2)`` A (module docstring:
    Newton with held parameters, one step carrying them) and the inverse's current error."""
    held = jax.tree_util.tree_map(jax.lax.stop_gradient, p)
    current = jax.vmap(_current, in_axes=(0, None))
    jac = jax.vmap(jax.jacfwd(_current), in_axes=(0, None))
    start = jnp.stack(
        [
            held["psi_f"] + _one_axis_start(i_dq[:, 0] + held["i_f"], held["a_y0"], held["a_yy"], held["T"]),
            _one_axis_start(i_dq[:, 1], held["a_x0"], held["a_xx"], held["S"]),
        ],
        -1,
    )

    def newton_step(psi, params):
        r = current(psi, params) - i_dq
        return _solve2(jac(psi, params), r), r

    def go_on(state):
        k, _, r = state
        return (k < NEWTON_ITERATIONS) & (jnp.max(jnp.abs(r)) > 0.01 * NEWTON_TOL_A)

    def iterate(state):
        k, psi, _ = state
        step, _ = newton_step(psi, held)
        scale = jnp.maximum(1.0, jnp.max(jnp.abs(step), axis=-1, keepdims=True) / NEWTON_STEP_WB)
        psi = psi - step / scale
        return k + 1, psi, current(psi, held) - i_dq

    r0 = jnp.full_like(i_dq, jnp.inf)
    psi = jax.lax.stop_gradient(jax.lax.while_loop(go_on, iterate, (0, start, r0))[1])
    step, r = newton_step(psi, p)
    psi = psi - step
    return psi, jnp.max(jnp.abs(jax.lax.stop_gradient(r)), axis=-1)


_flux_jit = jax.jit(_flux_at)


def _solve2(G, r):
    """``(N, 2)``: ``G^-1 r`` for ``(N, 2, 2)`` matrices in closed form (a batched LAPACK call costs more)."""
    det = G[:, 0, 0] * G[:, 1, 1] - G[:, 0, 1] * G[:, 1, 0]
    return (
        jnp.stack(
            [G[:, 1, 1] * r[:, 0] - G[:, 0, 1] * r[:, 1], G[:, 0, 0] * r[:, 1] - G[:, 1, 0] * r[:, 0]], -1
        )
        / det[:, None]
    )


def _ramp_mean(x, K: int):
    """JAX twin of the gridded fit's end averaging: the mean of ``x (N, ...)`` over each run of ``K``."""
    c = jnp.concatenate([jnp.zeros((1,) + x.shape[1:]), jnp.cumsum(x, axis=0)])
    return (c[K:] - c[:-K]) / K


#: Every parameter of the model and the window equations, in the order of `_Problem`'s arrays.
ALL_NAMES = (*COEFFICIENTS, "S", "T", "U", "V", "psi_f", "i_f", "R", "V_e")


class _Problem(eqx.Module):
    """The window equations' data and the parameter layout: every parameter is ``base + P y`` (``y`` the
    fitted unknowns), exponentiated where `is_log` (module docstring). The layout is data, not static, so
    the magnet's two forms share one compiled solve."""

    i_dq: jax.Array
    w_e: jax.Array
    half: jax.Array
    a: jax.Array
    b: jax.Array
    dU: jax.Array
    dI: jax.Array
    dE: jax.Array
    base: jax.Array
    P: jax.Array
    is_log: jax.Array
    K: int = eqx.field(static=True)

    def parameters(self, y):
        z = self.base + self.P @ y
        z = jnp.where(self.is_log, jnp.exp(jnp.where(self.is_log, z, 0.0)), z)
        return {name: z[k] for k, name in enumerate(ALL_NAMES)}

    def residuals(self, y, _args=None):
        """``(2 W,)`` Wb: each window's d and q equation, interleaved by window."""
        p = self.parameters(y)
        psi, _ = _flux_at(p, self.i_dq)
        K = self.K
        ends = _ramp_mean(psi, K)
        wpsi = self.w_e[:, None] * psi
        c = jnp.concatenate([jnp.zeros((1, 2)), jnp.cumsum(self.half * (wpsi[:-1] + wpsi[1:]), axis=0)])
        W = _ramp_mean(c, K)
        dpsi = ends[self.b] - ends[self.a]
        dW = W[self.b] - W[self.a]
        rest = p["R"] * self.dI + p["V_e"] * self.dE - self.dU
        r_d = dpsi[:, 0] - dW[:, 1] + rest[:, 0]
        r_q = dpsi[:, 1] + dW[:, 0] + rest[:, 1]
        return jnp.stack([r_d, r_q], -1).ravel()


@eqx.filter_jit
def _solve(problem: _Problem, y0, max_steps: int):
    """Levenberg-Marquardt from ``y0``: the optimum, the solver's last Jacobian ``(2 W, m)`` and residuals
    there (no second Jacobian compiled), the step count and success."""
    sol = optx.least_squares(
        problem.residuals,
        optx.LevenbergMarquardt(rtol=1e-9, atol=1e-9),
        y0,
        max_steps=max_steps,
        throw=False,
    )
    f_info = sol.state.f_info
    return (
        sol.value,
        f_info.jac.as_matrix(),
        f_info.residual,
        sol.stats["num_steps"],
        sol.result == optx.RESULTS.successful,
    )


def _linear_start(grid_fit: FluxMapFit, magnet: str, exponents: dict) -> dict:
    """Start values: the model fitted to the grid's measured nodes in the current domain (module docstring),
    linear in the coefficients and ``i_f`` with ``psi_f`` (``magnet="flux"``) the grid's flux at zero
    current; a coefficient the solve makes negative starts at a hundredth of its axis' linear term."""
    g = grid_fit.grid
    D, Q = np.meshgrid(g.i_d, g.i_q, indexing="ij")
    keep = grid_fit.measured & (Q >= 0)
    i_d, i_q = D[keep], Q[keep]
    psi_f = float(g.at(0.0, 0.0)[0][0]) if magnet == "flux" else 0.0
    y = g.psi_d[keep] - psi_f
    x = g.psi_q[keep]
    ax, ay = np.abs(x), np.abs(y)
    S, T, U, V = (exponents[k] for k in "STUV")
    zero = np.zeros_like(x)
    # columns: a_x0, a_xx, a_y0, a_yy, a_xy, i_f; rows: i_q then i_d
    rows_q = [x, ax**S * x, zero, zero, ax**U * ay ** (V + 2) / (V + 2) * x, zero]
    rows_d = [zero, zero, y, ay**T * y, ax ** (U + 2) * ay**V / (U + 2) * y, -np.ones_like(y)]
    A = np.vstack([np.column_stack(rows_q), np.column_stack(rows_d)])
    rhs = np.concatenate([i_q, i_d])
    if magnet != "mmf":
        A = A[:, :5]
    scale = np.linalg.norm(A, axis=0)
    c = np.linalg.lstsq(A / scale, rhs, rcond=None)[0] / scale
    a_x0, a_y0 = max(c[0], 1e-3 / max(float(np.ptp(x)), 1e-9)), max(c[2], 1e-3 / max(float(np.ptp(y)), 1e-9))
    out = {
        "a_x0": a_x0,
        "a_xx": c[1] if c[1] > 0 else 0.01 * a_x0,
        "a_y0": a_y0,
        "a_yy": c[3] if c[3] > 0 else 0.01 * a_y0,
        "a_xy": c[4] if c[4] > 0 else 0.01 * min(a_x0, a_y0),
        "i_f": float(c[5]) if magnet == "mmf" else 0.0,
        "psi_f": psi_f,
    }
    return out


def _fit_one(windows_data, grid_fit, R, inverter_error, magnet, exponents, start=None, y_start=None):
    """One Levenberg-Marquardt fit (`_Solved`); ``y_start`` replaces the start of the unknowns."""
    i_dq, w_e, wins, dE = windows_data
    start = dict(start or _linear_start(grid_fit, magnet, PAPER_EXPONENTS))
    fitted_exponents = exponents == "fitted"
    names, logs, y0 = [], [], []
    for name in COEFFICIENTS:
        names.append(name), logs.append(True), y0.append(math.log(start[name]))
    fixed = {"V": 0.0}
    for name in "STU":
        if fitted_exponents:
            names.append(name), logs.append(True), y0.append(math.log(start.get(name, PAPER_EXPONENTS[name])))
        else:
            fixed[name] = PAPER_EXPONENTS[name]
    for name in ("psi_f", "i_f"):
        if (magnet == "flux" and name == "psi_f") or (magnet == "mmf" and name == "i_f"):
            names.append(name), logs.append(False), y0.append(start[name])
        else:
            fixed[name] = 0.0
    if R is None:
        names.append("R"), logs.append(True), y0.append(math.log(max(grid_fit.R, 1e-6)))
    else:
        fixed["R"] = float(R)
    if inverter_error:
        names.append("V_e"), logs.append(False), y0.append(start.get("V_e", grid_fit.V_e or 0.0))
    else:
        fixed["V_e"] = 0.0
    over = lambda v: v[wins.b] - v[wins.a]  # noqa: E731
    base = np.array([fixed.get(n, 0.0) for n in ALL_NAMES])
    P = np.zeros((len(ALL_NAMES), len(names)))
    P[[ALL_NAMES.index(n) for n in names], np.arange(len(names))] = 1.0
    is_log = np.zeros(len(ALL_NAMES), dtype=bool)
    is_log[[ALL_NAMES.index(n) for n, log in zip(names, logs, strict=True) if log]] = True
    problem = _Problem(
        i_dq=jnp.asarray(i_dq),
        w_e=jnp.asarray(w_e),
        half=jnp.asarray(wins.half),
        a=jnp.asarray(wins.a),
        b=jnp.asarray(wins.b),
        dU=jnp.asarray(over(wins.U_int)),
        dI=jnp.asarray(over(wins.I_int)),
        dE=jnp.asarray(over(dE)),
        base=jnp.asarray(base),
        P=jnp.asarray(P),
        is_log=jnp.asarray(is_log),
        K=wins.K,
    )
    y0 = np.asarray(y0 if y_start is None else y_start, dtype=float)
    y, J, r, steps, ok = _solve(problem, jnp.asarray(y0), MAX_STEPS)
    r = np.asarray(r)
    return _Solved(
        problem, tuple(names), tuple(logs), y, np.asarray(J), r, int(steps), bool(ok), float(r @ r)
    )


@dataclasses.dataclass(frozen=True)
class _Solved:
    problem: _Problem
    names: tuple
    logs: tuple
    y: jax.Array
    J: np.ndarray
    r: np.ndarray
    steps: int
    ok: bool
    cost: float


def _entries(fit: _Solved, window_lags: int, inflation: float = 1.0) -> dict:
    """``{name: entry}`` with Gauss-Newton intervals (module docstring, "Intervals"), the covariance
    multiplied by ``inflation``."""
    y = fit.y
    cov = inflation * covariance([(fit.J, fit.r, (1, fit.r.size // 2), window_lags)])[0]
    se = np.sqrt(np.abs(np.diag(cov)))
    units = COEFFICIENTS | {"S": "", "T": "", "U": "", "psi_f": "Wb", "i_f": "A", "R": "ohm", "V_e": "V"}
    out = {}
    for k, (name, log) in enumerate(zip(fit.names, fit.logs, strict=True)):
        v, s = float(y[k]), float(se[k])
        ok = math.isfinite(s)
        if log:
            value, ci = math.exp(v), [math.exp(v - 1.96 * s), math.exp(v + 1.96 * s)] if ok else [None, None]
        else:
            value, ci = v, [v - 1.96 * s, v + 1.96 * s] if ok else [None, None]
        out[name] = {
            "value": value,
            "stderr": s if ok else None,
            "ci95": ci,
            "unit": units[name],
            "fitted_as": "log" if log else "value",
        }
    return out


def _refined_axes(grid: FluxMapGrid):
    """``(i_d, i_q, nearest)``: the axes of ``grid`` with `SAMPLING_REFINEMENT` intervals in each of its
    own, A, and the index ``(j, k)`` arrays of the original node nearest to each refined one."""
    axes, index = [], []
    for axis in (grid.i_d, grid.i_q):
        n = (axis.size - 1) * SAMPLING_REFINEMENT + 1
        axes.append(np.linspace(axis[0], axis[-1], n))
        index.append(np.rint(np.arange(n) / SAMPLING_REFINEMENT).astype(int))
    return axes[0], axes[1], np.ix_(index[0], index[1])


def _simex(fit, entries, data, log, grid_fit, R, inverter_error, form, exponents, lags):
    """The fit with the noisy-current bias extrapolated away (module docstring, "Noisy currents"): the
    unknowns ``2 y - mean(y_b)``, ``y_b`` refitted with fresh noise of the log's own level added to the
    currents, their covariance the fit's times ``1 + 1/draws``; returns ``(fit, entries)`` at them (the
    residual and the Newton check re-evaluated there)."""
    i_dq, w_e, wins, dE = data
    sigma = np.array([noise_level(i_dq[:, k], log.segments) for k in range(2)])
    if not np.all(sigma > 0):
        return fit, entries
    rng = np.random.default_rng(0)  # the extrapolation is repeatable: the same log gives the same fit
    ys = []
    for _ in range(SIMEX_DRAWS):
        noisy = i_dq + sigma * rng.standard_normal(i_dq.shape)
        I_int = wins.cum(wins.half * (noisy[:-1] + noisy[1:]))
        dE_b = dE
        if inverter_error:
            e = _inverter_error_per_volt(noisy, log.theta_e, grid_fit.error_smoothing_a)
            dE_b = wins.cum(wins.half * (e[:-1] + e[1:]))
        data_b = (noisy, w_e, dataclasses.replace(wins, I_int=I_int), dE_b)
        refit = _fit_one(data_b, grid_fit, R, inverter_error, form, exponents, y_start=fit.y)
        if not refit.ok:
            return fit, entries
        ys.append(np.asarray(refit.y))
    y = 2.0 * np.asarray(fit.y) - np.mean(ys, axis=0)
    r = np.asarray(fit.problem.residuals(jnp.asarray(y)))
    corrected = dataclasses.replace(fit, y=jnp.asarray(y), r=r, cost=float(r @ r))
    out = _entries(corrected, lags, inflation=1.0 + 1.0 / SIMEX_DRAWS)
    for name, e in out.items():
        e["bias_removed"] = (
            math.exp(float(y[list(fit.names).index(name)]) - float(fit.y[list(fit.names).index(name)])) - 1.0
            if e["fitted_as"] == "log"
            else float(y[list(fit.names).index(name)] - fit.y[list(fit.names).index(name)])
        )
    return corrected, out


def fit_power_law_flux_map(
    log,
    pole_pairs: int,
    *,
    step_a: float | None = None,
    window_s: float = 2e-3,
    stride: int = 2,
    R: float | None = None,
    inverter_error: bool = False,
    error_smoothing_a: float | None = None,
    exponents: str = "paper",
    magnet: str = "auto",
) -> FluxModelFit:
    """Fit the power-law model to ``log`` (a [`DriveLog`][tuning.identify.log.DriveLog]) with ``pole_pairs``
    (module docstring). `step_a`, `window_s` (s), `stride`, `R` (ohm, fixed when given), `inverter_error`,
    `error_smoothing_a` (A): as [`fit_flux_map`][tuning.identify.flux_map_fit.fit_flux_map], whose grid the
    model is sampled on; `exponents`: ``"paper"`` (S=5, T=1, U=1, V=0) or ``"fitted"`` (S, T, U);
    `magnet`: ``"auto"``, ``"flux"``, ``"mmf"`` or ``"none"``. Raises
    [`ParameterError`][pmsmjax.spec.validation.ParameterError] (one line) for a log it cannot use."""
    if exponents not in ("paper", "fitted"):
        raise ParameterError(f"exponents {exponents!r}: give 'paper' or 'fitted'.")
    if magnet not in ("auto",) + MAGNETS:
        raise ParameterError(f"magnet {magnet!r}: give 'auto', 'flux', 'mmf' or 'none'.")
    grid_fit = fit_flux_map(
        log,
        pole_pairs,
        step_a=step_a,
        window_s=window_s,
        stride=stride,
        R=R,
        inverter_error=inverter_error,
        error_smoothing_a=error_smoothing_a,
    )
    w_e, dt = _checked_speed(log, pole_pairs, R)
    wins = window_equations(log, w_e, dt, window_s, stride)
    i_dq = np.asarray(log.i_dq, dtype=float)
    if inverter_error:
        e = _inverter_error_per_volt(i_dq, log.theta_e, grid_fit.error_smoothing_a)
        dE = wins.cum(wins.half * (e[:-1] + e[1:]))
    else:
        dE = np.zeros_like(wins.I_int)
    data = (i_dq, w_e, wins, dE)
    # windows share samples up to a window (and its averaged ends) apart
    window = int(wins.b[0] - wins.a[0])
    lags = 2 * math.ceil((window + wins.K) / stride)
    with jax.enable_x64(True):
        kept = None
        for form in ("flux", "mmf") if magnet == "auto" else (magnet,):
            fit = _fit_one(data, grid_fit, R, inverter_error, form, "paper")
            if kept is None or fit.cost < kept[1].cost:
                kept = (form, fit)
        form, fit = kept
        entries = _entries(fit, lags)
        if magnet == "auto":
            lo, hi = entries["psi_f" if form == "flux" else "i_f"]["ci95"]
            if lo is not None and lo <= 0.0 <= hi:
                form, fit = "none", _fit_one(data, grid_fit, R, inverter_error, "none", "paper")
                entries = _entries(fit, lags)
        if exponents == "fitted":
            start = {n: e["value"] for n, e in entries.items()}
            start.setdefault("psi_f", 0.0), start.setdefault("i_f", 0.0)
            fit = _fit_one(data, grid_fit, R, inverter_error, form, "fitted", start=start)
            entries = _entries(fit, lags)
        fit, entries = _simex(fit, entries, data, log, grid_fit, R, inverter_error, form, exponents, lags)
        problem, y, steps, ok, cost = fit.problem, fit.y, fit.steps, fit.ok, fit.cost
        p = {k: float(v) for k, v in problem.parameters(y).items()}
        _, newton_r = _flux_jit(problem.parameters(y), problem.i_dq)
        newton_r = float(jnp.max(newton_r))
        g = grid_fit.grid
        i_d, i_q, nearest = _refined_axes(g)
        D, Q = np.meshgrid(i_d, i_q, indexing="ij")
        nodes = np.stack([D.ravel(), Q.ravel()], -1)
        psi_nodes, node_r = _flux_jit(problem.parameters(y), jnp.asarray(nodes))
        psi_nodes = np.asarray(psi_nodes).reshape(D.shape + (2,))
        node_r = float(jnp.max(node_r))
    if not ok or not math.isfinite(cost) or max(newton_r, node_r) > NEWTON_TOL_A:
        raise ParameterError(
            f"{log.source}: the power-law model's fit did not converge ({steps} Levenberg-Marquardt steps, "
            f"the flux inverse off by {max(newton_r, node_r):.3g} A): the log's map is not of the model's "
            "form; fit the grid (drop --flux-model power-law)."
        )
    model = PowerLawSaturation(**{k: p[k] for k in (*COEFFICIENTS, "S", "T", "U", "V", "i_f", "psi_f")})
    n_res = 2 * int(wins.a.size)
    residual = math.sqrt(cost / n_res)
    sampled = FluxMapGrid(i_d, i_q, psi_nodes[..., 0], psi_nodes[..., 1], source="power-law model fit")
    as_map = dataclasses.replace(
        grid_fit,
        grid=sampled,
        measured=grid_fit.measured[nearest],
        node_samples=grid_fit.node_samples[nearest],
        R=p["R"],
        V_e=p["V_e"] if inverter_error else None,
        residual_rms_wb=residual,
        constraints=0,
        q_symmetric=True,
    )
    return FluxModelFit(
        map=as_map,
        model=model,
        parameters=entries,
        magnet=form,
        exponents=exponents,
        grid_fit=grid_fit,
        residual_rms_wb=residual,
        newton_residual_a=max(newton_r, node_r),
        steps=steps,
    )
