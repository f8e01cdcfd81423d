"""Identification benchmark: accuracy, 95 % interval coverage and speed against SciPy.

The log: the book drive (design-rule gains) on
[`pmsmjax.recorded.synthetic_logs.ID_TEST_MOTOR`][pmsmjax.recorded.synthetic_logs.ID_TEST_MOTOR] running
[`tuning.identify.excitation.identification_scenario`][tuning.identify.excitation.identification_scenario] (2
s at 10 kHz), plus 1 % current and 0.5 % voltage noise
([`pmsmjax.recorded.synthetic_logs.ID_LOG_NOISE`][pmsmjax.recorded.synthetic_logs.ID_LOG_NOISE]), one noise
seed per fit. Every figure from one process:

1. ``identify`` on seed 0: wall time of the first call (compile included) and of a second call on
   another seed (the compiled program reused), and each parameter's error against the truth;
2. coverage: the share of `n_seeds` seeds whose 95 % interval holds the true value, per parameter, and
   the largest relative error over the seeds;
3. the same fit with ``scipy.optimize.least_squares`` (``method="lm"``, MINPACK, two-point finite-
   difference Jacobians) on the same residuals implemented in NumPy (same windows, same RK4 stages, same
   weights, same start), and the time ratio. SciPy gets one solve with the final weights and a start at
   the warm start, while the JAX time is the whole ``identify`` (its noise re-weighting included), so the
   ratio is conservative. "Equal accuracy": the two optima are compared in units of each parameter's
   standard error.

``main(json_path, quick)`` prints a table and writes JSON atomically; ``quick`` (a smoke run) uses 3
seeds.
"""

import argparse
import time

import jax
import numpy as np
import scipy.optimize

from benchmarks.bench_core import machine_info, publish
from pmsmjax.recorded.synthetic_logs import (
    ID_LOG_NOISE,
    ID_TEST_MOTOR,
    add_measurement_noise,
    identification_log,
)
from tuning.identify import NAMES, IdentifyOptions, identify
from tuning.identify.excitation import identification_scenario
from tuning.identify.fit import _solve_and_linearise
from tuning.identify.log import drive_log_from_columns

__all__ = ["run", "main", "format_table", "numpy_residuals"]

_COLUMNS = ("time", "u_d", "u_q", "i_d", "i_q", "omega_m", "theta_e")


def _values(pmap, theta: np.ndarray) -> dict:
    out, j = {}, 0
    start, scale = np.asarray(pmap.start), np.asarray(pmap.scale)
    for k, name in enumerate(pmap.names):
        if pmap.free[k]:
            out[name] = start[k] * np.exp(theta[j]) if pmap.positive[k] else start[k] + scale[k] * theta[j]
            j += 1
        else:
            out[name] = start[k]
    return out


def numpy_residuals(theta: np.ndarray, pmap, ed: dict, md: dict) -> np.ndarray:
    """The residuals of [`tuning.identify.fit.joint_residuals`][tuning.identify.fit.joint_residuals] in NumPy
    (one RK4 sub-step, no dead time).

    `ed`, `md`: the electrical and mechanical window data as dicts of NumPy arrays.
    """
    p = _values(pmap, theta)
    i_meas, dt, u, w_e = ed["i"], ed["dt"], ed["u"], ed["w_e"]
    n_w, W = dt.shape

    def field(x, u_j, we_j):
        did = (u_j[:, 0] - p["R"] * x[:, 0] + we_j * p["L_q"] * x[:, 1]) / p["L_d"]
        diq = (u_j[:, 1] - p["R"] * x[:, 1] - we_j * (p["L_d"] * x[:, 0] + p["psi_f"])) / p["L_q"]
        return np.stack([did, diq], axis=1)

    x = i_meas[:, 0].copy()
    sim = np.empty((n_w, W, 2))
    for k in range(W):
        h = dt[:, k, None]
        k1 = field(x, u[:, k, 0], w_e[:, k, 0])
        k2 = field(x + 0.5 * h * k1, u[:, k, 1], w_e[:, k, 1])
        k3 = field(x + 0.5 * h * k2, u[:, k, 1], w_e[:, k, 1])
        k4 = field(x + h * k3, u[:, k, 2], w_e[:, k, 2])
        x = x + (h / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)
        sim[:, k] = x
    r_e = ((sim - i_meas[:, 1:]) / ed["sigma"]).reshape(-1)

    torque = 1.5 * md["pole_pairs"] * (p["psi_f"] * md["i"][..., 1] + (p["L_d"] - p["L_q"]) * md["i"][..., 0]
                                       * md["i"][..., 1]) - md["load"]  # fmt: skip
    w = md["w"][:, 0].copy()
    for k in range(md["dt"].shape[1]):
        h, t0, t1 = md["dt"][:, k], torque[:, k], torque[:, k + 1]
        f = lambda tau, x, h=h, t0=t0, t1=t1: (t0 + (t1 - t0) * tau / h - p["T_c"] - p["B"] * x) / p["J"]
        k1 = f(0.0, w)
        k2 = f(0.5 * h, w + 0.5 * h * k1)
        k3 = f(0.5 * h, w + 0.5 * h * k2)
        k4 = f(h, w + h * k3)
        w = w + (h / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)
    r_m = (w - md["w"][:, -1]) / md["sigma"]
    return np.concatenate([r_e, r_m])


def _log(clean, seed):
    return drive_log_from_columns(
        {k: v for k, v in add_measurement_noise(clean, ID_LOG_NOISE, seed=seed).items() if k in _COLUMNS}, 4
    )


def run(n_seeds: int = 50, first_seed: int = 0) -> dict:
    """Every figure of the module docstring; coverage over seeds ``first_seed .. first_seed + n_seeds - 1``
    (the timing and SciPy figures always use seeds 0 and 1)."""
    with jax.enable_x64(True):
        t0 = time.perf_counter()
        clean = identification_log(identification_scenario())
        sim_s = time.perf_counter() - t0
    opts = IdentifyOptions(pole_pairs=4)
    first = identify(_log(clean, 0), opts)
    second = identify(_log(clean, 1), opts)
    truth = {n: ID_TEST_MOTOR[n] for n in NAMES}

    covered = {n: 0 for n in NAMES}
    max_err = {n: 0.0 for n in NAMES}
    seed_times = []
    for seed in range(first_seed, first_seed + n_seeds):
        res = first if seed == 0 else second if seed == 1 else identify(_log(clean, seed), opts)
        seed_times.append(res.summary["wall_time_s"])
        for n in NAMES:
            p = res.summary["parameters"][n]
            lo, hi = p["ci95"]
            covered[n] += lo is not None and lo <= truth[n] <= hi
            max_err[n] = max(max_err[n], abs(p["value"] / truth[n] - 1.0))

    # SciPy on the same residuals, weights and start as the JAX fit of seed 0.
    fit = first.fit
    ed = {k: np.asarray(getattr(fit.electrical, k)) for k in ("i", "dt", "u", "w_e", "sigma")}
    md = {k: np.asarray(getattr(fit.mechanical, k)) for k in ("i", "dt", "w", "load", "sigma")}
    md["pole_pairs"] = fit.mechanical.pole_pairs
    t0 = time.perf_counter()
    r0 = numpy_residuals(np.zeros(fit.pmap.n_free), fit.pmap, ed, md)
    residual_s = time.perf_counter() - t0
    calls = [0]

    def counted(theta, *args):
        calls[0] += 1
        return numpy_residuals(theta, *args)

    t0 = time.perf_counter()
    sp = scipy.optimize.least_squares(
        counted, np.zeros(fit.pmap.n_free), args=(fit.pmap, ed, md), method="lm", xtol=1e-10, ftol=1e-10
    )
    scipy_s = time.perf_counter() - t0
    # The JAX solve alone (compiled), same start, weights and residuals: like for like with SciPy.
    with jax.enable_x64(True):
        y0 = jax.numpy.zeros(fit.pmap.n_free, jax.numpy.float64)
        args = (fit.pmap, fit.electrical, fit.mechanical)
        jax.block_until_ready(_solve_and_linearise(y0, args, 100, 1e-6))
        t0 = time.perf_counter()
        jax_solve = jax.block_until_ready(_solve_and_linearise(y0, args, 100, 1e-6))
        jax_solve_s = time.perf_counter() - t0
    se = np.sqrt(np.diag(fit.cov))
    agreement = np.abs(sp.x - fit.theta) / se
    cost_jax = 0.5 * float(np.sum(numpy_residuals(fit.theta, fit.pmap, ed, md) ** 2))
    sp_values = _values(fit.pmap, sp.x)

    return {
        "n_seeds": n_seeds,
        "first_seed": first_seed,
        "log": {
            "samples": int(clean["time"].size),
            "duration_s": float(clean["time"][-1] + 1e-4),
            "current_noise": 0.01,
            "voltage_noise": 0.005,
            "simulate_s": sim_s,
        },  # fmt: skip
        "truth": truth,
        "seed0": {
            "wall_time_first_call_s": first.summary["wall_time_s"],
            "wall_time_second_call_s": second.summary["wall_time_s"],
            "rel_error": {n: first.summary["parameters"][n]["value"] / truth[n] - 1.0 for n in NAMES},
            "rel_stderr": {n: first.summary["parameters"][n]["stderr"] / truth[n] for n in NAMES},
            "lm_steps": first.summary["solver"]["steps"],
        },
        "coverage": {n: covered[n] / n_seeds for n in NAMES},
        "max_rel_error": max_err,
        "median_wall_time_after_compile_s": float(np.median(seed_times[1:])) if n_seeds > 1 else None,
        "scipy": {
            "wall_time_s": scipy_s,
            "residual_calls": calls[0],
            "numpy_residual_s": residual_s,
            "n_residuals": int(r0.size),
            "status": int(sp.status),
            "cost": float(sp.cost),
            "cost_jax_optimum": cost_jax,
            "max_difference_in_stderr": float(agreement.max()),
            "rel_error": {n: sp_values[n] / truth[n] - 1.0 for n in NAMES},
        },
        "jax_single_solve_s": jax_solve_s,
        "jax_single_solve_steps": int(jax_solve[3]),
        "ratio_scipy_over_jax_single_solve": scipy_s / jax_solve_s,
        "ratio_scipy_over_jax_first_call": scipy_s / first.summary["wall_time_s"],
        "ratio_scipy_over_jax_second_call": scipy_s / second.summary["wall_time_s"],
        "machine": machine_info(),
    }


def format_table(r: dict) -> str:
    s0, sp = r["seed0"], r["scipy"]
    lines = [
        f"pmsmjax identification benchmark: {r['log']['samples']} samples ({r['log']['duration_s']:.1f} s), "
        f"1 % current / 0.5 % voltage noise, {r['n_seeds']} seeds from {r['first_seed']}",
        f"machine: {r['machine']['cpu']}, {r['machine']['cpu_count']} cores, jax {r['machine']['jax']}",
        "",
        f"{'param':6s} {'truth':>10s} {'err seed0':>10s} {'stderr':>9s} {'max err':>9s} {'coverage':>9s} "
        f"{'scipy err':>10s}",
    ]
    for n in NAMES:
        lines.append(
            f"{n:6s} {r['truth'][n]:10.4g} {100 * s0['rel_error'][n]:+9.3f}% "
            f"{100 * s0['rel_stderr'][n]:8.3f}% {100 * r['max_rel_error'][n]:8.3f}% "
            f"{100 * r['coverage'][n]:8.0f}% {100 * sp['rel_error'][n]:+9.3f}%"
        )
    lines += [
        "",
        f"JAX identify, first call (compile included): {s0['wall_time_first_call_s']:.2f} s; "
        f"second call: {s0['wall_time_second_call_s']:.2f} s; median after compile: "
        f"{r['median_wall_time_after_compile_s']:.2f} s ({s0['lm_steps']} LM steps on seed 0)",
        f"SciPy least_squares (lm, finite differences, NumPy residuals): {sp['wall_time_s']:.2f} s, "
        f"{sp['residual_calls']} residual evaluations of {1e3 * sp['numpy_residual_s']:.0f} ms",
        f"JAX solve alone (compiled, same start and weights): {r['jax_single_solve_s']:.2f} s "
        f"({r['jax_single_solve_steps']} LM steps)",
        f"ratio SciPy / JAX: {r['ratio_scipy_over_jax_single_solve']:.1f}x (solve against solve), "
        f"{r['ratio_scipy_over_jax_second_call']:.1f}x (whole identify, compiled), "
        f"{r['ratio_scipy_over_jax_first_call']:.2f}x (whole identify, compile included)",
        f"equal accuracy: optima differ by at most {sp['max_difference_in_stderr']:.3g} standard errors; "
        f"cost SciPy {sp['cost']:.6g} vs JAX {sp['cost_jax_optimum']:.6g}",
    ]
    return "\n".join(lines)


def main(json_path: str | None = None, quick: bool = False, n_seeds: int = 50, first_seed: int = 0) -> dict:
    results = run(n_seeds=3 if quick else n_seeds, first_seed=first_seed)
    results["quick"] = quick
    return publish(results, format_table(results), json_path)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="pmsmjax identification benchmark")
    parser.add_argument("--json", help="write the figures to this JSON file")
    parser.add_argument("--quick", action="store_true", help="3 seeds (a smoke run)")
    parser.add_argument("--seeds", type=int, default=50, help="noise seeds for the coverage (default 50)")
    parser.add_argument("--first-seed", type=int, default=0, help="first coverage seed (default 0)")
    args = parser.parse_args()
    main(args.json, quick=args.quick, n_seeds=args.seeds, first_seed=args.first_seed)
