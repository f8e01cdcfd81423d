"""A measured flux map of a saturated PMSM: ``psi_d(i_d, i_q)``, ``psi_q(i_d, i_q)`` on a rectangular grid,
its checks and its interpolant (pure NumPy at load; the same interpolant runs in JAX inside the plant,
[`pmsmjax.machines.pmsm_flux_map`][pmsmjax.machines.pmsm_flux_map]).

**The grid.** Uniformly spaced, sorted axes ``i_d (n_d,)``, ``i_q (n_q,)`` (A, at least 3 points each) and
flux arrays ``psi_d, psi_q (n_d, n_q)`` (Wb, peak phase flux linkage, amplitude-invariant dq frame), with
cross-saturation (each flux depends on both currents). Uniform spacing lets the plant find a point's cell
by one division instead of a search; measured maps are taken on uniform grids.

**The interpolant: bicubic Hermite, C1.** On each cell the flux is the bicubic polynomial that matches
the value, both first derivatives and the cross derivative at the four corners (e.g. de Boor, "A
Practical Guide to Splines", or Fritsch & Carlson's cubic Hermite form in two variables). The node
derivatives are finite differences of the grid (central inside, second-order one-sided at the edges), so
the interpolant needs no global solve and is local (a cell depends on its 4 x 4 neighbourhood). Why this:
the plant integrates ``di/dt = L_inc(i)^-1 (...)``, so the incremental inductances ``L_inc = dpsi/di`` must
be continuous (bilinear interpolation makes them jump at every cell edge, which RK4 sees as an error of
order one step); Hermite patches share value and gradient on each edge, so ``L_inc`` is continuous, and
the interpolant reproduces any bilinear map (in particular a linear machine) exactly. Its error on a
smooth map is O(h^3) in the flux (the finite-difference node slopes, O(h^2), times h). A cubic spline is
C2 but needs a global solve and rings near a measured kink; a C1 interpolant is what the ODE needs.

**Outside the grid** the flux is extended linearly with the boundary's incremental inductance:
``psi(i) = psi(i_c) + L_inc(i_c) (i - i_c)`` with ``i_c`` the current clipped to the grid, so ``L_inc``
stays continuous and positive definite, but is only an extrapolation:
[`excursion`][pmsmjax.machines.flux_map.excursion] reports how far a run went outside the measured range.

**Reciprocity.** A lossless magnetic circuit has ``dpsi_d/di_q = dpsi_q/di_d``; measured maps miss that by
a few mH (measurement noise, iron loss, a skewed rotor). They are accepted as measured: the checks need
only the symmetric part of ``L_inc`` positive definite (so ``i . dpsi > 0``: the machine stores energy
when current rises in any direction) and each flux rising along its own axis. A non-reciprocal map's
co-energy depends slightly on the path; the plant's torque ``1.5 p (psi_d i_q - psi_q i_d)`` does not use it.
"""

import dataclasses
import functools
import math

import numpy as np

from pmsmjax.spec.validation import ParameterError, plain

__all__ = [
    "FluxMapGrid",
    "hermite_coefficients",
    "flux_and_inductance",
    "locate",
    "evaluate",
    "excursion",
    "MIN_POINTS",
]

#: Fewest points per axis: second-order one-sided slopes at the edges need three.
MIN_POINTS = 3
#: Relative spread of the axis steps accepted as uniform (a CSV rounds its currents).
UNIFORM_TOLERANCE = 1e-6

# Cubic Hermite basis: [1, s, s^2, s^3] @ _HERMITE @ [f(0), f(1), f'(0), f'(1)] on a unit interval.
_HERMITE = np.array(
    [[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [-3.0, 3.0, -2.0, -1.0], [2.0, -2.0, 1.0, 1.0]]
)


@dataclasses.dataclass(frozen=True, eq=False)
class FluxMapGrid:
    """A checked flux map (module docstring), checked on construction.

    Args:
        i_d: ``(n_d,)`` d-axis current axis, A, uniformly spaced and increasing.
        i_q: ``(n_q,)`` q-axis current axis, A, uniformly spaced and increasing.
        psi_d: ``(n_d, n_q)`` d-axis flux linkage, Wb (row ``j``: ``i_d[j]``; column ``k``: ``i_q[k]``).
        psi_q: ``(n_d, n_q)`` q-axis flux linkage, Wb, laid out as ``psi_d``.
        source: Where the map came from (a file path), for messages.

    Raises:
        ParameterError: For a map the interpolant cannot use (`check_grid`), naming ``source``.
    """

    i_d: np.ndarray
    i_q: np.ndarray
    psi_d: np.ndarray
    psi_q: np.ndarray
    source: str = "flux map"

    def __post_init__(self):
        for name in ("i_d", "i_q", "psi_d", "psi_q"):
            object.__setattr__(self, name, np.asarray(getattr(self, name), dtype=float))
        check_grid(self)

    @property
    def lower(self) -> np.ndarray:
        """``(2,)`` smallest grid currents ``[i_d, i_q]``, A."""
        return np.array([self.i_d[0], self.i_q[0]])

    @property
    def upper(self) -> np.ndarray:
        """``(2,)`` largest grid currents, A."""
        return np.array([self.i_d[-1], self.i_q[-1]])

    @property
    def step(self) -> np.ndarray:
        """``(2,)`` grid spacing, A."""
        return (self.upper - self.lower) / (np.array([self.i_d.size, self.i_q.size]) - 1.0)

    def node_inductances(self) -> np.ndarray:
        """Incremental inductance ``dpsi/di`` at every grid point (the interpolant's own slopes there).

        Returns:
            ``(n_d, n_q, 2, 2)`` inductances, H.
        """
        d = _node_slopes(np.stack([self.psi_d, self.psi_q]), self.step, np)
        return np.stack([np.stack([d[0][0], d[1][0]], -1), np.stack([d[0][1], d[1][1]], -1)], -2)

    def coefficients(self, xp=np):
        """Bicubic coefficients of every cell
        ([`hermite_coefficients`][pmsmjax.machines.flux_map.hermite_coefficients]).

        Args:
            xp: ``numpy`` or ``jax.numpy``.

        Returns:
            ``(n_d - 1, n_q - 1, 2, 4, 4)`` coefficients.
        """
        psi = xp.stack([xp.asarray(self.psi_d), xp.asarray(self.psi_q)])
        return hermite_coefficients(psi, self.step, xp)

    @functools.cached_property
    def numpy_coefficients(self) -> np.ndarray:
        """[`coefficients`][pmsmjax.machines.flux_map.FluxMapGrid.coefficients] in float64 NumPy, computed
        once per map: the checks evaluate them many times and the plant's interpolant is made of them."""
        return self.coefficients()

    def flux(self, i_dq) -> tuple[np.ndarray, np.ndarray]:
        """``(psi (..., 2) Wb, L_inc (..., 2, 2) H)`` of the interpolant at the currents ``i_dq (..., 2)`` A,
        in NumPy, all points in one call
        ([`flux_and_inductance`][pmsmjax.machines.flux_map.flux_and_inductance], the plant's own)."""
        i = np.asarray(i_dq, dtype=float)
        return flux_and_inductance(self.numpy_coefficients, self.lower, self.step, self.upper, i, np)

    def at(self, i_d: float, i_q: float) -> tuple[np.ndarray, np.ndarray]:
        """``(psi (2,) Wb, L_inc (2, 2) H)`` of the interpolant at one point (NumPy, for design rules)."""
        return self.flux(np.array([i_d, i_q], dtype=float))

    def linear_model(self, i_q: float = 0.0) -> dict:
        """The linear machine a controller designs with.

        Args:
            i_q: q-axis current at which the incremental inductances are taken, A.

        Returns:
            ``{"psi_f", "L_d", "L_q"}``: ``psi_f = psi_d(0, 0)`` (Wb) and the incremental inductances
            ``L_d = dpsi_d/di_d``, ``L_q = dpsi_q/di_q`` at ``(0, i_q)`` (H).
        """
        psi0, _ = self.at(0.0, 0.0)
        _, L = self.at(0.0, i_q)
        return {"psi_f": float(psi0[0]), "L_d": float(L[0, 0]), "L_q": float(L[1, 1])}


def check_grid(grid: FluxMapGrid) -> None:
    """Refuse a map the interpolant cannot use (module docstring, "The grid" and "Reciprocity").

    Args:
        grid: The map.

    Raises:
        ParameterError: For the first check the map fails, naming its source.
    """
    where = grid.source
    for name in ("i_d", "i_q"):
        axis = getattr(grid, name)
        if axis.ndim != 1 or axis.size < MIN_POINTS:
            raise ParameterError(
                f"{where}: the {name} axis needs at least {MIN_POINTS} values (a 1-D grid axis, A), "
                f"got shape {axis.shape}."
            )
    shape = (grid.i_d.size, grid.i_q.size)
    for name in ("psi_d", "psi_q"):
        if getattr(grid, name).shape != shape:
            raise ParameterError(
                f"{where}: {name} has shape {getattr(grid, name).shape}, the grid is {shape} (i_d x i_q): "
                "one flux value per grid point, rows along i_d."
            )
    for name in ("i_d", "i_q", "psi_d", "psi_q"):
        values = getattr(grid, name)
        if not np.all(np.isfinite(values)):
            k = np.argwhere(~np.isfinite(values))[0]
            raise ParameterError(
                f"{where}: {name} is not finite at index {tuple(int(x) for x in k)}: fill the grid point "
                "(every grid point needs a measured flux) or crop the grid."
            )
    for name in ("i_d", "i_q"):
        axis = getattr(grid, name)
        steps = np.diff(axis)
        if np.any(steps <= 0):
            raise ParameterError(f"{where}: the {name} axis must increase strictly (sort the grid, A).")
        if np.ptp(steps) > UNIFORM_TOLERANCE * steps.mean():
            raise ParameterError(
                f"{where}: the {name} axis is not uniformly spaced (steps {plain(steps.min())} to "
                f"{plain(steps.max())} A): resample the map on a regular grid."
            )
    for name, axis, other in (("psi_d", 0, "i_d"), ("psi_q", 1, "i_q")):
        rise = np.diff(getattr(grid, name), axis=axis)
        if np.any(rise <= 0):
            j, k = (int(x) for x in np.argwhere(rise <= 0)[0])
            at = (grid.i_d[j], grid.i_q[k])
            raise ParameterError(
                f"{where}: {name} does not rise with {other} at i_d = {plain(at[0])} A, "
                f"i_q = {plain(at[1])} A: "
                "a flux map's own-axis flux increases with its current; check the column order and signs."
            )
    L = grid.node_inductances()
    sym = 0.5 * (L + np.swapaxes(L, -1, -2))
    det = sym[..., 0, 0] * sym[..., 1, 1] - sym[..., 0, 1] * sym[..., 1, 0]
    bad = (det <= 0) | (sym[..., 0, 0] <= 0)
    if np.any(bad):
        j, k = (int(x) for x in np.argwhere(bad)[0])
        Lm = L[j, k] * 1e3
        raise ParameterError(
            f"{where}: the incremental inductance at i_d = {plain(grid.i_d[j])} A, "
            f"i_q = {plain(grid.i_q[k])} A "
            f"([[{Lm[0, 0]:.3g}, {Lm[0, 1]:.3g}], [{Lm[1, 0]:.3g}, {Lm[1, 1]:.3g}]] mH) is not positive "
            "definite (its symmetric part): the map stores no energy there; check for a noisy or "
            "mislabelled column."
        )


def _axis_slope(f, h, axis: int, xp):
    """Finite-difference derivative of ``f`` along ``axis`` (spacing ``h``): central inside, second-order
    one-sided at both ends (exact for quadratics, so a bilinear map's slopes are exact)."""
    f = xp.moveaxis(f, axis, 0)
    inner = (f[2:] - f[:-2]) / (2.0 * h)
    first = (-3.0 * f[0] + 4.0 * f[1] - f[2]) / (2.0 * h)
    last = (3.0 * f[-1] - 4.0 * f[-2] + f[-3]) / (2.0 * h)
    return xp.moveaxis(xp.concatenate([first[None], inner, last[None]]), 0, axis)


def _node_slopes(psi, step, xp):
    """``((d/di_d, d/di_q) of psi_d, (...) of psi_q)`` at the nodes; ``psi (2, n_d, n_q)``."""
    return tuple((_axis_slope(p, step[0], 0, xp), _axis_slope(p, step[1], 1, xp)) for p in psi)


def hermite_coefficients(psi, step, xp=np):
    """Bicubic Hermite coefficients of every cell.

    Args:
        psi: ``(2, n_d, n_q)`` fluxes ``[psi_d, psi_q]``, Wb.
        step: ``(2,)`` grid spacing, A.
        xp: ``numpy`` or ``jax.numpy``.

    Returns:
        ``(n_d - 1, n_q - 1, 2, 4, 4)``: ``psi_x(s, t) = [1 s s^2 s^3] C [1 t t^2 t^3]^T`` with ``s, t`` in
        [0, 1] the position inside the cell along i_d and i_q.
    """
    h_d, h_q = step[0], step[1]
    f = psi
    f_d = _axis_slope(f, h_d, 1, xp) * h_d  # slopes in cell units (per unit s, t)
    f_q = _axis_slope(f, h_q, 2, xp) * h_q
    f_dq = _axis_slope(_axis_slope(f, h_d, 1, xp), h_q, 2, xp) * (h_d * h_q)

    def corners(g):  # (2, n_d-1, n_q-1, 2, 2): g at the cell corners [[00, 01], [10, 11]]
        return xp.stack(
            [xp.stack([g[:, :-1, :-1], g[:, :-1, 1:]], -1), xp.stack([g[:, 1:, :-1], g[:, 1:, 1:]], -1)], -2
        )

    # F = [[f, f_q], [f_d, f_dq]] at the corners, as the 4x4 block Hermite data matrix.
    F = xp.concatenate(
        [xp.concatenate([corners(f), corners(f_q)], -1), xp.concatenate([corners(f_d), corners(f_dq)], -1)],
        -2,
    )
    M = xp.asarray(_HERMITE)
    C = xp.einsum("ab,xjkbc,dc->xjkad", M, F, M)
    return xp.moveaxis(C, 0, 2)


def flux_and_inductance(coefficients, lower, step, upper, i_dq, xp=np):
    """The map at one current or many, extended linearly outside the grid (module docstring).

    **Arguments:** `coefficients` from
    [`hermite_coefficients`][pmsmjax.machines.flux_map.hermite_coefficients]; `lower`, `step`, `upper`:
    ``(2,)`` grid corners and spacing, A; `i_dq`: ``(..., 2)`` currents, A; `xp`: ``numpy`` or ``jax.numpy``.

    **Returns:** ``psi (..., 2)`` Wb and the incremental inductance ``L (..., 2, 2)`` H,
    ``L[..., r, c] = dpsi_r / di_c``.

    One implementation for both namespaces: the plant runs it in JAX on one point (``(2,)``), the checks
    before a run in NumPy on many points at once. Each point's arithmetic is the same elementwise
    sequence either way (no sum, matmul or fused reduction), so NumPy on a batch gives, point by point, the
    bits NumPy gives on that point alone, and JAX's agree with them to float64 rounding (XLA may contract
    a product and a sum into one fused multiply-add).
    """
    where = locate(coefficients.shape[:2], lower, step, upper, i_dq, xp)
    return evaluate(coefficients, step, where, xp)


def locate(n_cells, lower, step, upper, i_dq, xp=np):
    """Where the currents ``i_dq (..., 2)`` (A) lie on the grid: ``(..., 6)`` ``[cell_d, cell_q, s, t,
    outside_d, outside_q]``: the cell's indices (as floats), the position inside it (``s, t`` in [0, 1])
    and how far the current lies outside the grid along each axis (A, 0 inside), from the grid shape
    `n_cells` ``(2,)``, corners `lower`, `upper` and spacing `step` (A).

    The clamps are comparisons and selects, not ``clip``: XLA:CPU compiles ``clip``'s NaN-propagating
    min/max into several instructions each, and this chain sits on the plant's critical path at every RK4
    stage (docs/performance.md, "Saturated machines"). A NaN current still gives a NaN flux (NaN fails every
    comparison and passes through).

    Args:
        n_cells: ``(2,)`` the grid's cell counts.
        lower: ``(2,)`` lowest grid corner, A.
        step: ``(2,)`` grid spacing, A.
        upper: ``(2,)`` highest grid corner, A.
        i_dq: ``(2,)`` current, A.
        xp: ``numpy`` or ``jax.numpy``.

    Returns:
        ``(6,)`` ``[cell_d, cell_q, s, t, outside_d, outside_q]``: the cell's indices (as floats), the
        position inside it (``s, t`` in [0, 1]) and how far the current lies outside the grid along each
        axis (A, 0 inside).
    """
    i_c = xp.where(i_dq < lower, lower, i_dq)
    i_c = xp.where(i_c > upper, upper, i_c)
    x = (i_c - lower) * (1.0 / step)
    cell = xp.floor(x)  # >= 0: the current is clamped to the grid
    last = xp.asarray(n_cells, dtype=x.dtype) - 1
    cell = xp.where(cell > last, last, cell)  # the upper edge belongs to the last cell (s = 1)
    return xp.concatenate([cell, x - cell, i_dq - i_c], axis=-1)


def _per_point(x):
    """A per-point value ``(...)`` against the per-point ``(..., 2)`` flux components: unchanged for one
    point (so the plant's traced program is the single-point one), a trailing axis for a batch."""
    return x if x.ndim == 0 else x[..., None]


def evaluate(coefficients, step, where, xp=np):
    """``(psi (..., 2) Wb, L_inc (..., 2, 2) H)`` of the map at the points
    [`locate`][pmsmjax.machines.flux_map.locate] gave (`where` ``(..., 6)``), extended linearly outside the
    grid with the edge's incremental inductance."""
    cell = where[..., :2].astype(int)
    s, t = _per_point(where[..., 2]), _per_point(where[..., 3])
    C = coefficients[cell[..., 0], cell[..., 1]]  # (..., 2, 4, 4)
    # Nested (Horner) products written out on slices, with no sum or matmul: on CPU each reduction or
    # small dot is a kernel of its own, and inside the plant's integration loop the kernel count sets the
    # cost (measured: sums made the flux-map drive 18x the linear one, matmuls 60x).
    rows = [((C[..., a, 3] * t + C[..., a, 2]) * t + C[..., a, 1]) * t + C[..., a, 0] for a in range(4)]
    rows_dt = [(3.0 * C[..., a, 3] * t + 2.0 * C[..., a, 2]) * t + C[..., a, 1] for a in range(4)]
    psi = ((rows[3] * s + rows[2]) * s + rows[1]) * s + rows[0]
    dpsi_ds = (3.0 * rows[3] * s + 2.0 * rows[2]) * s + rows[1]
    dpsi_dt = ((rows_dt[3] * s + rows_dt[2]) * s + rows_dt[1]) * s + rows_dt[0]
    L = xp.stack([dpsi_ds * (1.0 / step[0]), dpsi_dt * (1.0 / step[1])], -1)
    return psi + L[..., 0] * _per_point(where[..., 4]) + L[..., 1] * _per_point(where[..., 5]), L


def excursion(grid_lower, grid_upper, i_dq) -> dict:
    """How far currents went outside a map's grid.

    Args:
        grid_lower: ``(2,)`` lowest grid corner, A.
        grid_upper: ``(2,)`` highest grid corner, A.
        i_dq: ``(..., 2)`` currents of a run, A (any leading shape: periods, batch).

    Returns:
        ``{"i_d_range", "i_q_range"}`` (reached ``[min, max]``, A), ``"grid_i_d"``, ``"grid_i_q"`` (the
        grid's), ``"outside_a"``: the largest distance outside the grid along either axis, A (0 inside), and
        ``"warning"``: one line for the user, or ``None`` when the run stayed on the grid.
    """
    i = np.asarray(i_dq, dtype=float).reshape(-1, 2)
    lo, hi = np.asarray(grid_lower, dtype=float), np.asarray(grid_upper, dtype=float)
    reached_lo, reached_hi = i.min(axis=0), i.max(axis=0)
    outside = float(np.max(np.maximum(np.maximum(lo - reached_lo, reached_hi - hi), 0.0)))
    out = {
        "i_d_range": [float(reached_lo[0]), float(reached_hi[0])],
        "i_q_range": [float(reached_lo[1]), float(reached_hi[1])],
        "grid_i_d": [float(lo[0]), float(hi[0])],
        "grid_i_q": [float(lo[1]), float(hi[1])],
        "outside_a": outside,
        "warning": None,
    }
    if outside > 0 and math.isfinite(outside):
        out["warning"] = (
            f"the run left the flux map's grid by {outside:.3g} A (i_d reached {reached_lo[0]:.3g} to "
            f"{reached_hi[0]:.3g} A on a {lo[0]:.3g} to {hi[0]:.3g} A grid, i_q {reached_lo[1]:.3g} to "
            f"{reached_hi[1]:.3g} A on {lo[1]:.3g} to {hi[1]:.3g} A): outside it the flux is a linear "
            "extrapolation; measure a wider map or lower the current limit."
        )
    return out
