"""The least-squares fit of identification: one optimistix Levenberg-Marquardt solve for all unknowns.

The residual vector has two groups, each divided by its own noise level:

- electrical ([`tuning.identify.electrical`][tuning.identify.electrical]): simulated minus measured dq
  currents over shooting windows, which involve R, L_d, L_q, psi_f (and V_dt) only, because the speed is
  measured;
- mechanical ([`tuning.identify.mechanical`][tuning.identify.mechanical]): simulated minus measured speed at
  the end of short windows, which involve J, B, T_c and, through the torque, psi_f, L_d, L_q.

The equations decouple given the measured speed and currents, so the warm starts are computed per
group (linear equation error: electrical first, the mechanical one with its torque). The output-error
solve is joint because one compiled program is cheaper than two (compile time dominates a single fit),
and the joint covariance then carries the electrical uncertainty into J and B by itself.

Forward-mode JAX Jacobians (optimistix default), float64. After a solve the noise level of each
signal is re-estimated from its residuals (degrees of freedom shared in proportion) and, if one moved
by more than 2 %, the solve is repeated with the new weights, so the final weights are the noise
estimates. One compiled program per log shape serves every log of that shape (and every repeat).
"""

import dataclasses

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jax.flatten_util import ravel_pytree

from tuning.identify import electrical as el
from tuning.identify import mechanical as me
from tuning.identify.parameters import ParameterMap
from tuning.identify.uncertainty import covariance, interval_dof
from tuning.parameters import set_leaves

__all__ = ["FitResult", "fit", "noise_level", "joint_residuals"]


@dataclasses.dataclass
class FitResult:
    """Result of [`fit`][tuning.identify.fit.fit].

    - `pmap`, `theta`: parameter map and solver coordinates at the optimum; `values`: ``{name: value}``.
    - `cov`: ``(n_free, n_free)`` covariance of ``theta`` (sandwich, robust to correlated residuals);
      `cov_white`: the plain Gauss-Newton ``s2 M^-1``; `M`: information ``Jr^T Jr``; `s2`: variance
      factor (about 1 with noise-level weights).
    - `sigma`: ``{signal: noise level}`` used as weights (i_d, i_q in A; omega_end in rad/s).
    - `electrical`, `mechanical`: the windowed data; `residuals`: simulated minus measured,
      ``i_dq (n_w, W, 2)`` A and ``omega_end (n_m,)`` rad/s; `lags`: Newey-West lags of each group.
    - `dof`: ``(n_free,)`` effective degrees of freedom of each variance estimate (the intervals' t
      quantile, [`tuning.identify.uncertainty.interval_dof`][tuning.identify.uncertainty.interval_dof]).
    - `steps`: Levenberg-Marquardt steps (all solves); `ok`: the solver converged.
    """

    pmap: ParameterMap
    theta: np.ndarray
    values: dict
    cov: np.ndarray
    cov_white: np.ndarray
    M: np.ndarray
    s2: float
    sigma: dict
    electrical: el.ElectricalData
    mechanical: me.MechanicalData
    residuals: dict
    lags: dict
    dof: np.ndarray
    steps: int
    ok: bool


def noise_level(x: np.ndarray, bounds=None) -> float:
    """Robust white-noise standard deviation of a smooth signal plus noise: MAD of the second difference
    (taken inside each capture ``bounds[s]:bounds[s + 1]`` of a burst log, none across a gap).

    For white noise of variance s^2 the second difference has variance 6 s^2; the smooth part of a
    current sampled at 10 kHz contributes little, and the median ignores the samples where it does.
    """
    if bounds is None or len(bounds) <= 2:
        d2 = np.diff(x, 2)
    else:
        d2 = np.concatenate([np.diff(x[a:b], 2) for a, b in zip(bounds[:-1], bounds[1:], strict=True)])
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / np.sqrt(6.0))


def joint_residuals(theta, args):
    """``(electrical (n_w, W, 2), mechanical (n_m,))`` weighted residuals; args ``(pmap, edata, mdata)``."""
    pmap, edata, mdata = args
    return el.electrical_residuals(theta, (pmap, edata)), me.mechanical_residuals(theta, (pmap, mdata))


@eqx.filter_jit
def _solve_and_linearise(y0, args, max_steps: int, rtol: float):
    """Levenberg-Marquardt from ``y0``; returns the optimum, the dense Jacobian ``(n_res, n_free)`` and the
    flat residuals there (the solver's own last linearisation, so no second Jacobian is compiled), the
    step count and success."""
    sol = optx.least_squares(
        joint_residuals, optx.LevenbergMarquardt(rtol=rtol, atol=rtol), y0, args=args, max_steps=max_steps,
        throw=False,
    )  # fmt: skip
    f_info = sol.state.f_info
    resid = ravel_pytree(f_info.residual)[0]
    return (
        sol.value,
        f_info.jac.as_matrix(),
        resid,
        sol.stats["num_steps"],
        sol.result == optx.RESULTS.successful,
    )


def fit(log, pole_pairs: int, *, hold, fixed, start, dead_time, dead_time_eps, windows, n_substeps,
        max_steps=100, rtol=1e-6, held=(), temperature_coeffs=None) -> FitResult:  # fmt: skip
    """Fit every free parameter to a [`DriveLog`][tuning.identify.log.DriveLog].

    `fixed`: ``{name: value}`` held fixed; `held`: names held at their warm start (the log does not
    determine them:
    [`tuning.identify.uncertainty.motion_excitation`][tuning.identify.uncertainty.motion_excitation]);
    `start`: start values replacing the warm start; `windows`: ``(electrical, mechanical)`` shooting-window
    lengths in log intervals; `hold`, `dead_time`, `dead_time_eps`, `n_substeps`: model options
    ([`tuning.identify.electrical`][tuning.identify.electrical]); `temperature_coeffs`: known temperature
    coefficients of R and psi_f
    ([`tuning.identify.temperature_scaling`][tuning.identify.temperature_scaling]), applied when the log has a
    temperature.
    """
    e_names = el.ELECTRICAL_NAMES if dead_time else el.ELECTRICAL_NAMES[:4]
    e_fixed = {n: fixed[n] for n in e_names if n in fixed}
    e_start, _ = el.warm_start(
        log, pole_pairs, hold, e_fixed, dead_time, temperature_coeffs=temperature_coeffs
    )
    e_start.update({n: start[n] for n in e_names if n in start})
    e_vals = {n: fixed.get(n, e_start.get(n)) for n in e_names}
    mdata = me.MechanicalData.from_log(
        log, windows[1], 1.0, pole_pairs, temperature_coeffs=temperature_coeffs
    )
    m_fixed = {n: fixed[n] for n in me.MECHANICAL_NAMES if n in fixed}
    m_start, sigma_w = me.warm_start(mdata, e_vals, m_fixed)
    m_start.update({n: start[n] for n in me.MECHANICAL_NAMES if n in start})

    names = e_names + me.MECHANICAL_NAMES
    values = {**e_vals, **{n: fixed.get(n, m_start.get(n)) for n in me.MECHANICAL_NAMES}}
    fixed = {**fixed, **{n: values[n] for n in held if n not in fixed}}
    positive = tuple(n not in ("V_dt", "T_c") for n in names)
    # Signed parameters move in steps of 1 V (V_dt) and 10 mN m (T_c).
    scale = [1.0 if n == "V_dt" else 0.01 if n == "T_c" else 1.0 for n in names]
    pmap = ParameterMap(
        names,
        tuple(n not in fixed for n in names),
        positive,
        jnp.asarray([values[n] for n in names], jnp.float64),
        jnp.asarray(scale, jnp.float64),
    )
    sigma_i = np.array([noise_level(log.i_dq[:, 0], log.segments), noise_level(log.i_dq[:, 1], log.segments)])
    sigma_i = np.maximum(sigma_i, 1e-9 + 1e-6 * np.max(np.abs(log.i_dq)))
    sigma_w = max(sigma_w, 1e-12)
    edata = el.ElectricalData.from_log(log, windows[0], sigma_i, pole_pairs, hold, n_substeps, dead_time,
                                       dead_time_eps, temperature_coeffs)  # fmt: skip
    y = jnp.zeros(pmap.n_free, jnp.float64)
    steps_total, ok = 0, True
    for _ in range(3):
        mdata = set_leaves(mdata, ["sigma"], [jnp.asarray(sigma_w, jnp.float64)])
        edata = set_leaves(edata, ["sigma"], [jnp.asarray(sigma_i, jnp.float64)])
        y, jac, r, steps, ok = _solve_and_linearise(y, (pmap, edata, mdata), max_steps, rtol)
        steps_total += int(steps)
        n_e = int(np.prod(edata.i[:, 1:].shape))  # electrical rows come first
        jac, r = np.asarray(jac), np.asarray(r)
        je, re, jm, rm = jac[:n_e], r[:n_e], jac[n_e:], r[n_e:]
        m = pmap.n_free
        n = re.size + rm.size
        r2 = re.reshape(-1, 2) ** 2
        new_i = sigma_i * np.sqrt(r2.sum(axis=0) / (r2.shape[0] * (n - m) / n))
        new_w = sigma_w * np.sqrt(float(rm @ rm) / (rm.size * (n - m) / n))
        moved = np.abs(np.append(new_i / sigma_i, new_w / sigma_w) - 1.0)
        if np.all(moved < 0.02):
            break
        sigma_i, sigma_w = new_i, new_w
    values = {k: float(v) for k, v in pmap.values(y).items()}
    # Residual correlation length: a few electrical time constants (electrical group); consecutive
    # mechanical windows share a boundary sample and coloured current noise: 3 windows.
    tau = max(values["L_d"], values["L_q"]) / values["R"]
    lags_e = int(min(np.ceil(10.0 * tau / float(np.median(np.diff(log.time)))), edata.dt.shape[1] // 2))
    lags_m = 3
    cov, cov_white, s2, M = covariance([(je, re, edata.dt.shape, lags_e), (jm, rm, (1, rm.size), lags_m)])
    # Independent blocks for the intervals' degrees of freedom: each electrical window (it restarts from
    # a measurement), and runs of lags_m + 1 mechanical windows (correlated over lags_m windows).
    info = lambda j: np.einsum("gki,gkj->gij", j, j)
    edges = np.arange(0, rm.size, lags_m + 1)
    blocks = np.concatenate(
        [info(je.reshape(edata.dt.shape[0], -1, pmap.n_free))]
        + [info(jm[None, a : a + lags_m + 1]) for a in edges]
    )
    dof = interval_dof(M, blocks)
    return FitResult(
        pmap=pmap,
        theta=np.asarray(y),
        values=values,
        cov=cov,
        cov_white=cov_white,
        M=M,
        s2=s2,
        sigma={"i_d": float(sigma_i[0]), "i_q": float(sigma_i[1]), "omega_end": float(sigma_w)},
        electrical=edata,
        mechanical=mdata,
        residuals={"i_dq": re.reshape(edata.i[:, 1:].shape) * sigma_i, "omega_end": rm * sigma_w},
        lags={"electrical": lags_e, "mechanical": lags_m},
        dof=dof,
        steps=steps_total,
        ok=bool(ok),
    )
