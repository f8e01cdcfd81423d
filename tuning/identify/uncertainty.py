"""Gauss-Newton standard errors, 95 % intervals and the identifiability check of a least-squares fit.

For weighted residuals ``r(y)`` (each divided by its signal's noise level) at the optimum, with Jacobian
``Jr`` and ``n`` residuals for ``m`` unknowns, the noise variance factor is ``s^2 = |r|^2 / (n - m)``
(1 when the weights are the true noise levels) and ``cov(y) = s^2 (Jr^T Jr)^-1`` in solver coordinates
(``log`` of positive parameters, so variances are relative). When residuals are correlated in time
the sandwich form of [`covariance`][tuning.identify.uncertainty.covariance] is used instead (same estimate,
honest spread).

**Identifiability.** The covariance is eigen-decomposed; a direction whose standard deviation exceeds
the tolerance is one the data does not pin down, and the parameters with a large share of it are
reported together (one name: that parameter is not determined; several: they cannot be separated, only
a combination of them is). A parameter is ``identifiable`` when its own relative standard error is
below the tolerance (default 5 %). Directions with a numerically zero eigenvalue get an infinite
standard error rather than the zero a pseudo-inverse would give: no confident value from no data.

**Interval width.** The robust variance is estimated from a limited number of independent blocks
(shooting windows): for a parameter whose information comes from a few of them (psi_f from the
high-speed windows, L_q from the q-current steps) that estimate is itself noisy, and a normal 1.96
interval around it covers the truth less than 95 % of the time (measured: 88 % for psi_f over 50
seeds). [`interval_dof`][tuning.identify.uncertainty.interval_dof] gives each parameter the effective degrees
of freedom of its variance estimate (Bell-McCaffrey / Imbens-Kolesar, the standard small-sample correction for
cluster-robust standard errors), and the interval uses the Student t quantile with those degrees of freedom.
"""

import numpy as np

__all__ = [
    "covariance",
    "score_covariance",
    "interval_dof",
    "weak_directions",
    "excitation",
    "motion_excitation",
    "ADVICE",
    "MIN_EXCITATION",
    "EXCITED_BY",
]

#: What excitation determines each parameter (shown for parameters the data did not determine).
ADVICE = {
    "R": "current at low speed or standstill, or q-current steps at a constant speed (R i_q against "
    "the back-EMF)",
    "L_d": "d-axis current injection: steps or a PRBS on id_ref of a few A (tuning.identify.excitation)",
    "L_q": "q-axis current changes: speed steps or q-current steps",
    "psi_f": "running at several speeds (the back-EMF grows with speed)",
    "V_dt": "current through zero in every phase at low voltage (slow rotation at load)",
    "J": "accelerations: speed steps",
    "B": "several constant speeds (both directions)",
    "T_c": "several constant speeds (both directions)",
}


#: A current axis excites its inductance when its variation, averaged over ``EXCITATION_AVERAGE_S``,
#: is at least this many times its noise level (see [`excitation`][tuning.identify.uncertainty.excitation]).
MIN_EXCITATION = 3.0
EXCITATION_AVERAGE_S = 0.5e-3
#: Parameter -> the dq current axis (0: d, 1: q) whose variation determines it.
EXCITED_BY = {"L_d": 0, "L_q": 1}


def excitation(
    time: np.ndarray, i_dq: np.ndarray, average_s: float = EXCITATION_AVERAGE_S, bounds=None
) -> dict:
    """How much each current axis varies beyond its noise: ``{"L_d": {...}, "L_q": {...}}``.

    **Why.** L_d is determined only by how i_d moves (``L_d di_d/dt`` in the d equation, ``w_e L_d i_d``
    in the q equation, where a constant i_d merges with psi_f). On a log whose i_d is held at zero by a PI
    loop, what moves i_d is the loop reacting to its own measurement noise: the output-error fit then
    explains noise with L_d, and because that motion is correlated with the logged voltage (and the voltage
    carries noise the plant never saw) its covariance can be small around a value far from the truth
    (measured: L_d 1.4-2.0x off, reported identifiable, on scipy-made closed-loop logs at 3000-6000 rad/s
    current bandwidth; tests/tuning/test_identify_honesty.py). So the covariance alone cannot be trusted
    there; this check asks the data directly.

    **What.** For each axis: the noise level ``sigma`` from first differences (``std(diff) / sqrt 2``, exact
    for white noise on a smooth signal, an overestimate otherwise), and the RMS variation of the signal
    after a centred moving average over `average_s` (which leaves ``sigma / sqrt(m)`` of the noise of ``m``
    averaged samples). ``ratio = rms / sigma``: noise alone gives about ``1 / sqrt(m)`` (0.45 at 10 kHz),
    an i_d PRBS of +-3 A over 0.045 A of noise about 30; measured on i_d ~ 0 logs 0.2-0.6. An inductance
    whose axis has ``ratio < MIN_EXCITATION`` is reported not identifiable whatever its covariance says.
    The differences and averages of a burst log are taken inside each capture (`bounds`, ``(S + 1,)`` rows).
    """
    dt = float(np.median(np.diff(time)))
    m = max(1, int(round(average_s / dt)))
    parts = _captures(bounds)
    out = {}
    for name, axis in EXCITED_BY.items():
        x = np.asarray(i_dq[:, axis], dtype=float)
        if parts is None:
            sigma = float(np.std(np.diff(x)) / np.sqrt(2.0))
            smooth = np.convolve(x, np.ones(m) / m, mode="valid") if x.size >= m else x
        else:
            sigma = float(np.std(np.concatenate([np.diff(x[a:b]) for a, b in parts])) / np.sqrt(2.0))
            avg = lambda v: np.convolve(v, np.ones(m) / m, mode="valid") if v.size >= m else v
            smooth = np.concatenate([avg(x[a:b]) for a, b in parts])
        rms = float(np.sqrt(np.mean((smooth - smooth.mean()) ** 2)))
        ratio = rms / sigma if sigma > 0 else np.inf
        out[name] = {
            "current": "i_d" if axis == 0 else "i_q",
            "variation_rms_a": rms,
            "noise_a": sigma,
            "ratio": float(ratio),
            "excited": bool(ratio >= MIN_EXCITATION),
        }
    return out


def motion_excitation(omega_m: np.ndarray, load: str, bounds=None) -> dict:
    """Whether the speed of a log carries what psi_f, J and B need: ``{name: {"excited", "reason"}}``.

    **Why.** The mechanical residuals compare the logged speed with the speed the torque would give. On a
    log whose speed never changes (a dynamometer holding it, or standstill) the speed carries no
    acceleration: J multiplies ``dw/dt = 0`` and the fit runs J off to infinity, where every torque error
    vanishes. Its weight (the speed-residual noise) then collapses, and with it the whole covariance:
    measured on a constant-speed log of ID_TEST_MOTOR, J 1.7e8 x the truth and every parameter reported
    not identifiable although R, L_d, L_q, psi_f were within 0.2 % (tests/tuning/test_identify_starved.py).
    So such parameters are held at their warm start and reported not identifiable before the fit.

    **What.** J needs the speed to change; B, with a constant load torque estimated beside it, needs
    several speeds (at one speed ``B w`` is one more constant), and without one (``load = "none"``) a
    speed other than zero; psi_f needs rotation (at standstill ``w_e psi_f = 0`` and the torque has no
    motion to show). "Changes" means a spread (max - min) above 1e-9 of the largest speed plus the speed's
    own noise (first differences, inside each capture of a burst log: `bounds`), so that a noisy constant
    speed does not count.
    """
    w = np.asarray(omega_m, dtype=float)
    scale = float(np.max(np.abs(w))) if w.size else 0.0
    parts = _captures(bounds)
    diffs = np.diff(w) if parts is None else np.concatenate([np.diff(w[a:b]) for a, b in parts])
    noise = float(np.std(diffs) / np.sqrt(2.0)) if w.size > 1 else 0.0
    varies = float(np.ptp(w)) > MIN_EXCITATION * noise + 1e-9 * scale if w.size else False
    turns = scale > MIN_EXCITATION * noise and scale > 0.0
    b_ok = varies if load == "constant" else turns
    return {
        "J": {"excited": bool(varies), "reason": "the speed never changes (no acceleration)"},
        "B": {
            "excited": bool(b_ok),
            "reason": "one constant speed: B w is one more constant beside the load torque"
            if load == "constant"
            else "the rotor never turns",
        },
        "psi_f": {"excited": bool(turns), "reason": "the rotor never turns (no back-EMF)"},
    }


def _captures(bounds):
    """``[(first row, end row)]`` of the captures of a burst log, or None for one capture."""
    if bounds is None or len(bounds) <= 2:
        return None
    return list(zip(bounds[:-1], bounds[1:], strict=True))


def _inverse(M: np.ndarray) -> np.ndarray:
    """Inverse of a symmetric information matrix, with infinite variance along null directions."""
    p = M.shape[0]
    lam, V = np.linalg.eigh(0.5 * (M + M.T))
    tiny = max(lam.max(), 0.0) * 1e-13
    inv_lam = np.where(lam > tiny, 1.0 / np.where(lam > tiny, lam, 1.0), np.inf)
    with np.errstate(invalid="ignore"):
        inv = np.einsum("ik,k,jk->ij", V, inv_lam, V)
    # An inf direction makes every parameter touching it inf; 0 * inf from untouched ones is 0, not NaN.
    touched = (np.abs(V) > 1e-12) & ~np.isfinite(inv_lam)[None, :]
    bad = touched.any(axis=1)
    inv = np.where(np.isnan(inv), 0.0, inv)
    inv[bad, :] = np.where(np.eye(p, dtype=bool)[bad], np.inf, inv[bad, :])
    return inv


def score_covariance(scores: np.ndarray, lags: int) -> np.ndarray:
    """Newey-West (Bartlett) long-run covariance ``(m, m)`` of per-sample scores ``(S, T, m)``.

    ``S`` independent series (shooting windows) of ``T`` samples; correlation is summed up to `lags`
    samples apart within each series with weights ``1 - l / (lags + 1)``.
    """
    m = scores.shape[-1]
    flat = lambda x: x.reshape(-1, m)
    out = flat(scores).T @ flat(scores)
    for lag in range(1, min(lags, scores.shape[1] - 1) + 1):
        G = flat(scores[:, lag:]).T @ flat(scores[:, :-lag])  # a matrix product: BLAS, not einsum
        out += (1.0 - lag / (lags + 1.0)) * (G + G.T)
    return out


def covariance(groups) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """``(cov, cov_white, s2, M)``: covariances ``(m, m)`` of the unknowns, variance factor, information.

    `groups`: residual groups ``(jac (n, m), resid (n,), series (S, T), lags)``: weighted Jacobian and
    residuals at the optimum; the rows as ``S`` independent series of ``T`` samples (a sample may own
    several rows, summed into one score); correlation length `lags`, samples.
    ``cov_white = s2 M^-1`` with ``M = sum jac^T jac`` assumes independent residuals. ``cov`` is the
    sandwich ``M^-1 S M^-1`` with ``S`` the Newey-West covariance of the per-sample scores
    ``jac_k^T r_k``: it stays right when the residuals are correlated in time (noise on the logged
    voltages reaches the currents through the machine's low-pass, so the current residuals are not
    white).
    """
    m = groups[0][0].shape[1]
    n = sum(g[1].size for g in groups)
    s2 = float(sum(g[1] @ g[1] for g in groups)) / max(n - m, 1)
    M = sum(g[0].T @ g[0] for g in groups)
    inv = _inverse(M)
    cov_white = s2 * inv
    S = np.zeros((m, m))
    for jac, resid, series, lags in groups:
        scores = (jac * resid[:, None]).reshape(series[0], series[1], -1, m).sum(axis=2)
        S += score_covariance(scores, lags)
    finite = np.isfinite(np.diag(inv))
    inv0 = np.where(np.isfinite(inv), inv, 0.0)
    cov = inv0 @ S @ inv0
    cov[~finite, :] = cov_white[~finite, :]
    cov[:, ~finite] = cov_white[:, ~finite]
    return cov, cov_white, s2, M


def interval_dof(M: np.ndarray, blocks: np.ndarray) -> np.ndarray:
    """``(m,)`` effective degrees of freedom of each parameter's robust variance estimate.

    `M`: ``(m, m)`` information ``Jr^T Jr``; `blocks`: ``(G, m, m)`` the information of each of ``G``
    independent blocks of residuals (their sum is `M`). For parameter ``j``, with ``l = M^-1 e_j`` and
    ``F_g = l^T M_g``, the variance estimate ``sum_g (l^T s_g)^2`` (``s_g`` a block's score) is, under a
    working model of independent equal-variance residuals, a quadratic form whose matrix has the
    nonzero eigenvalues of the ``(G, G)`` matrix ``Q = diag(F_g l) - F M^-1 F^T`` (the second term: the
    fitted residuals are orthogonal to the Jacobian). Satterthwaite's match of a scaled chi-square gives
    ``dof = tr(Q)^2 / tr(Q^2)``: ``G - 1`` when every block informs equally, fewer when a few dominate.
    Parameters without finite variance get ``inf`` (they get no interval anyway).
    """
    m = M.shape[0]
    inv = _inverse(M)
    inv0 = np.where(np.isfinite(inv), inv, 0.0)
    out = np.full(m, np.inf)
    for j in range(m):
        if not np.all(np.isfinite(inv[:, j])):
            continue
        ell = inv[:, j]
        F = blocks @ ell  # (G, m): F_g = M_g l (M_g symmetric)
        Q = np.diag(F @ ell) - F @ inv0 @ F.T
        den = float(np.sum(Q * Q))
        if den > 0:
            out[j] = float(np.trace(Q)) ** 2 / den
    return out


def weak_directions(cov: np.ndarray, names, tol: float) -> list[dict]:
    """Directions of the covariance ``cov`` (solver coordinates) with standard deviation above `tol`.

    Each entry: ``{"std": float or None (infinite), "parameters": [names with a large share],
    "weights": [their components, the largest scaled to 1]}``. A parameter with infinite variance is a
    direction of its own.
    """
    out = []
    inf = ~np.isfinite(np.diag(cov))
    for j in np.flatnonzero(inf):
        out.append({"std": None, "parameters": [names[j]], "weights": [1.0]})
    keep = np.flatnonzero(~inf)
    if keep.size:
        lam, V = np.linalg.eigh(cov[np.ix_(keep, keep)])
        for k in range(lam.size):
            std = float(np.sqrt(max(lam[k], 0.0)))
            if std <= tol:
                continue
            v = V[:, k] / np.max(np.abs(V[:, k]))
            share = [j for j in np.argsort(-np.abs(v)) if abs(v[j]) >= 0.3]
            out.append(
                {
                    "std": std,
                    "parameters": [names[keep[j]] for j in share],
                    "weights": [float(v[j]) for j in share],
                }
            )
    return out
