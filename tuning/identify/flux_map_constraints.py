"""The flux-map fit's least squares under the constraints that make the map an energy-storing one: at every
grid node the incremental inductance's symmetric part positive definite (at least a floor, H, along every
direction) and each flux rising with its own current between neighbouring nodes.

**Linear in the node fluxes.** The interpolant's node inductances are finite differences of the node fluxes
([`pmsmjax.machines.flux_map.FluxMapGrid.node_inductances`][pmsmjax.machines.flux_map.FluxMapGrid.node_inductances]),
so for a direction ``v`` the stored-energy condition ``v^T L_sym v >= L_floor`` is one linear inequality in
the unknowns, as is each rise. Positive definiteness is every direction at once: the fit adds, node by node,
the direction of the smallest eigenvalue wherever the current solution falls below the floor (cutting
planes; each cut is a condition the answer must meet anyway, so the cuts never exclude it), until none does.

**The solver.** Least squares with linear inequalities (LSI) reduced to least distance (LDP) and solved by
non-negative least squares, Lawson and Hanson, "Solving Least Squares Problems", Prentice-Hall 1974, ch. 23
(SciPy's ``nnls``): with ``M = Q R`` (columns scaled to unit norm), ``x = R^-1 (z + Q^T b)`` and
``min |z|`` subject to ``G R^-1 z >= h - G R^-1 Q^T b``. Exact, no step size, no tolerance to tune.

**Fewer unknowns than nodes.** When the map is parametrised by fewer unknowns ``y`` (the d-axis symmetric
map: the half grid ``i_q >= 0``, [`tuning.identify.flux_map_fit`][tuning.identify.flux_map_fit]), the full
node vector is ``x = E y``: the constraints are formed on ``x`` and act on ``y`` through ``E``, and only the
nodes that are not mirror images of others are checked (a mirrored node's condition is the same row).
"""

import numpy as np
from scipy.linalg import qr, solve_triangular
from scipy.optimize import nnls

from pmsmjax.machines.flux_map import _axis_slope
from pmsmjax.spec.validation import ParameterError

__all__ = [
    "slope_operators",
    "symmetric_inductances",
    "node_inductance_rows",
    "solve_constrained",
    "factor",
    "CUT_ROUNDS",
]

#: Most rounds of cuts before the constraints are given up as unsatisfiable.
CUT_ROUNDS = 40


def slope_operators(n_d: int, n_q: int, step) -> tuple[np.ndarray, np.ndarray]:
    """``(S_d, S_q)``, each ``(n_d n_q, n_d n_q)``: the interpolant's node slopes along i_d and i_q
    (Wb/A per Wb) as matrices acting on a raveled ``(n_d, n_q)`` node array."""
    eye = np.eye(n_d * n_q).reshape(n_d * n_q, n_d, n_q)
    S_d = _axis_slope(eye, float(step[0]), 1, np).reshape(n_d * n_q, -1).T
    S_q = _axis_slope(eye, float(step[1]), 2, np).reshape(n_d * n_q, -1).T
    return S_d, S_q


def symmetric_inductances(x, S_d, S_q) -> np.ndarray:
    """``(n_d n_q, 2, 2)``: the symmetric part of every node's incremental inductance, H, of the unknowns
    ``x = [psi_d nodes, psi_q nodes, ...]`` (Wb)."""
    n = S_d.shape[0]
    psi_d, psi_q = x[:n], x[n : 2 * n]
    L = np.empty((n, 2, 2))
    L[:, 0, 0], L[:, 1, 1] = S_d @ psi_d, S_q @ psi_q
    L[:, 0, 1] = L[:, 1, 0] = 0.5 * (S_q @ psi_d + S_d @ psi_q)
    return L


def node_inductance_rows(S_d, S_q, node: int, v, n_columns: int) -> np.ndarray:
    """``(n_columns,)``: ``v^T L_sym v`` at ``node`` as a row acting on the unknowns ``[psi_d nodes,
    psi_q nodes, ...]`` (``L_sym``: the symmetric part of the node's incremental inductance)."""
    n = S_d.shape[0]
    row = np.zeros(n_columns)
    c = v[0] * v[1]  # the symmetric part's off-diagonal is (dpsi_d/di_q + dpsi_q/di_d) / 2, counted twice
    row[:n] = v[0] ** 2 * S_d[node] + c * S_q[node]
    row[n : 2 * n] = v[1] ** 2 * S_q[node] + c * S_d[node]
    return row


def _violations(x, S_d, S_q, n_d, n_q, floor_h, rise_wb, n_columns, checked):
    """Rows ``(k, n_columns)`` and bounds ``(k,)`` of the constraints ``x`` breaks: the smallest-eigenvalue
    direction at each ``checked`` node (``(n_d n_q,)`` bool) whose symmetric inductance is below ``floor_h``,
    each pair of checked neighbours whose own-axis flux rises by less than ``rise_wb``."""
    n = n_d * n_q
    w, V = np.linalg.eigh(symmetric_inductances(x, S_d, S_q))
    rows, bounds = [], []
    for node in np.flatnonzero((w[:, 0] < floor_h * (1.0 - 1e-9)) & checked):
        rows.append(node_inductance_rows(S_d, S_q, node, V[node, :, 0], n_columns))
        bounds.append(floor_h)
    index = np.arange(n).reshape(n_d, n_q)
    for offset, first, second in ((0, index[:-1, :], index[1:, :]), (n, index[:, :-1], index[:, 1:])):
        flux = x[offset : offset + n]
        for a, b in zip(first.ravel(), second.ravel(), strict=True):
            if checked[a] and checked[b] and flux[b] - flux[a] < rise_wb * (1.0 - 1e-9):
                row = np.zeros(n_columns)
                row[offset + b], row[offset + a] = 1.0, -1.0
                rows.append(row)
                bounds.append(rise_wb)
    return rows, bounds


def factor(M, target) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(R, f, norms)``: the triangular factor of ``M`` with its columns scaled to unit ``norms``,
    ``f = Q^T target``; the unconstrained solution is ``R^-1 f / norms`` (`free_solution`)."""
    norms = np.linalg.norm(M, axis=0)
    norms[norms == 0] = 1.0
    Q, R = qr(M / norms, mode="economic")
    return R, Q.T @ target, norms


def free_solution(factored) -> np.ndarray:
    """The unconstrained least-squares solution of a
    [`factor`][tuning.identify.flux_map_constraints.factor]."""
    R, f, norms = factored
    return solve_triangular(R, f) / norms


def solve_constrained(
    factored, n_d: int, n_q: int, step, floor_h: float, where: str, expand=None, checked=None
) -> tuple[np.ndarray, int]:
    """``(x, cuts)``: the least-squares solution of ``M x ~ target`` (as
    [`factor`][tuning.identify.flux_map_constraints.factor] gives it; unknowns ``[psi_d nodes, psi_q nodes,
    others]``, or ``y`` with those ``expand @ y``, `expand` ``(2 n_d n_q + others, columns)``) whose map
    stores energy (module docstring) with inductances of at least ``floor_h`` H, and the number of
    constraints it took; `checked`: ``(n_d n_q,)`` bool, the nodes whose conditions are imposed (default
    all). Raises
    [`ParameterError`][pmsmjax.spec.validation.ParameterError] (one line, naming ``where``) if the
    constraints cannot be met."""
    R, f, norms = factored
    n_columns = R.shape[1]
    full = (lambda y: y) if expand is None else (lambda y: expand @ y)  # noqa: E731
    n_full = n_columns if expand is None else expand.shape[0]
    checked = np.ones(n_d * n_q, dtype=bool) if checked is None else np.asarray(checked, dtype=bool)

    def unscale(y):
        return y / norms

    x = free_solution(factored)
    S_d, S_q = slope_operators(n_d, n_q, step)
    rise_wb = 0.5 * floor_h * float(min(step))
    G, h = np.zeros((0, n_columns)), np.zeros(0)
    for _ in range(CUT_ROUNDS):
        rows, bounds = _violations(full(x), S_d, S_q, n_d, n_q, floor_h, rise_wb, n_full, checked)
        if not rows:
            return x, len(h)
        rows = np.array(rows) if expand is None else np.array(rows) @ expand
        G, h = np.vstack([G, rows]), np.concatenate([h, bounds])
        # in scaled unknowns y = norms x = R^-1 (z + f): G x = (G / norms) R^-1 (z + f) >= h
        GR = solve_triangular(R, (G / norms).T, trans="T").T  # (G / norms) R^-1
        E = np.vstack([GR.T, (h - GR @ f)[None, :]])
        F = np.zeros(E.shape[0])
        F[-1] = 1.0
        u, _ = nnls(E, F, maxiter=50 * E.shape[1])
        r = E @ u - F
        if abs(r[-1]) < 1e-12:
            break
        z = -r[:-1] / r[-1]
        x = unscale(solve_triangular(R, z + f))
    raise ParameterError(
        f"{where}: no energy-storing flux map fits the log (incremental inductances of at least "
        f"{floor_h * 1e3:.3g} mH at every grid point): check the column order and signs."
    )
