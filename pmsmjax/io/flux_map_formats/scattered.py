"""Flux at scattered currents onto a grid: measured operating points, a map's NaN holes, a map on a grid of
flux rather than current.

**The interpolant: SciPy's ``RBFInterpolator``, thin-plate spline with a linear polynomial**
(``kernel="thin_plate_spline"``, ``degree=1``), on the currents scaled to the unit square. Why this and not
``griddata``: ``griddata`` (linear or Clough-Tocher) is defined only inside the convex hull of the points,
so the grid points outside it would need a second rule, and a flat (nearest-value) fill there gives zero
incremental inductance, which the map's checks refuse (a flux that does not rise with its own current). The
thin-plate spline passes through every point (``smoothing = 0``), is smooth everywhere (the plant needs a
continuous incremental inductance) and continues the data outside the hull with its linear part and a
slowly growing ``r^2 log r`` term, the gentlest extension that still bends. A least-squares smooth fit
would average out measurement noise but also bias a saturating knee; give ``smoothing > 0`` for noisy
points. More than `DENSE_POINTS` points are interpolated from their `NEIGHBOURS` nearest (a dense solve grows
with the cube of the count).

**What is measured.** A grid point inside the convex hull of the data (SciPy's ``Delaunay``) lies between
measurements: it is marked measured. One outside the hull is an extrapolation and is marked not measured
(``measured = 0`` in the map's own CSV layout, [`pmsmjax.io.flux_map_files`][pmsmjax.io.flux_map_files]):
the plant uses it as the map's other points, but do not trust the map there.
"""

import math

import numpy as np

from pmsmjax.machines.flux_map import MIN_POINTS, FluxMapGrid
from pmsmjax.spec.validation import ParameterError

__all__ = ["grid_from_points", "fill_holes", "interpolate", "default_points", "DENSE_POINTS", "NEIGHBOURS"]

#: Above this many data points the spline is local (`NEIGHBOURS` nearest points per evaluation).
DENSE_POINTS = 1200
NEIGHBOURS = 48
#: Most grid points per axis a resampled map gets unless asked for more.
MAX_DEFAULT_POINTS = 65


def default_points(n_data: int) -> int:
    """Grid points per axis for ``n_data`` scattered points: about two per data spacing
    (``2 sqrt(n) + 1``), at least `MIN_POINTS`, at most `MAX_DEFAULT_POINTS`."""
    return int(min(MAX_DEFAULT_POINTS, max(MIN_POINTS, 2 * math.ceil(math.sqrt(n_data)) + 1)))


def interpolate(points_a, values, targets_a, smoothing: float = 0.0) -> np.ndarray:
    """The thin-plate spline through ``values (n, k)`` at ``points_a (n, 2)`` (A), at ``targets_a (m, 2)``
    (module docstring): ``(m, k)``. Both axes are scaled by the data's span first, so that i_d and i_q
    count alike."""
    from scipy.interpolate import RBFInterpolator

    points_a = np.asarray(points_a, dtype=float)
    low, span = points_a.min(axis=0), np.ptp(points_a, axis=0)
    span = np.where(span > 0, span, 1.0)
    scaled = (points_a - low) / span
    neighbours = None if len(points_a) <= DENSE_POINTS else NEIGHBOURS
    spline = RBFInterpolator(
        scaled, values, kernel="thin_plate_spline", degree=1, smoothing=smoothing, neighbors=neighbours
    )
    return spline((np.asarray(targets_a, dtype=float) - low) / span)


def _inside_hull(points_a, targets_a) -> np.ndarray:
    from scipy.spatial import Delaunay

    low, span = points_a.min(axis=0), np.ptp(points_a, axis=0)
    span = np.where(span > 0, span, 1.0)
    hull = Delaunay((points_a - low) / span)
    return hull.find_simplex((targets_a - low) / span, tol=1e-9) >= 0


def grid_from_points(
    i_d, i_q, psi_d, psi_q, where: str, n_points=None, smoothing: float = 0.0
) -> tuple[FluxMapGrid, np.ndarray]:
    """A grid map from scattered points (module docstring).

    Args:
        i_d: ``(n,)`` d-axis currents of the points, A (pmsmjax's axes: d along the magnet).
        i_q: ``(n,)`` q-axis currents, A.
        psi_d: ``(n,)`` d-axis flux linkage, Wb (peak, amplitude-invariant dq).
        psi_q: ``(n,)`` q-axis flux linkage, Wb.
        where: how messages name the file.
        n_points: ``(n_d, n_q)`` grid points per axis; default
            [`default_points`][pmsmjax.io.flux_map_formats.scattered.default_points] on both.
        smoothing: the spline's smoothing (0: through every point).

    Returns:
        The map on the uniform grid spanning the points' currents, and its ``(n_d, n_q)`` measured marks
        (False outside the points' convex hull).

    Raises:
        ParameterError: Too few points, a NaN, all points on one line, or a map the grid checks refuse.
    """
    cols = [np.asarray(c, dtype=float).reshape(-1) for c in (i_d, i_q, psi_d, psi_q)]
    if len({c.size for c in cols}) != 1:
        raise ParameterError(f"{where}: i_d, i_q, psi_d and psi_q need one value per point, as many each.")
    if not all(np.all(np.isfinite(c)) for c in cols):
        raise ParameterError(f"{where}: a point holds NaN or inf: drop the points that were not measured.")
    points = np.column_stack(cols[:2])
    if len(points) < 6 or min(np.unique(points[:, 0]).size, np.unique(points[:, 1]).size) < 2:
        raise ParameterError(
            f"{where}: {len(points)} points do not span an area of (i_d, i_q): give at least 6 points, "
            "at two or more values of each current."
        )
    if np.unique(points, axis=0).shape[0] != len(points):
        raise ParameterError(f"{where}: a current (i_d, i_q) appears twice: give one point per current.")
    n_d, n_q = n_points or (default_points(len(points)),) * 2
    axes = [np.linspace(points[:, k].min(), points[:, k].max(), n) for k, n in ((0, n_d), (1, n_q))]
    D, Q = np.meshgrid(*axes, indexing="ij")
    targets = np.column_stack([D.ravel(), Q.ravel()])
    try:
        inside = _inside_hull(points, targets).reshape(D.shape)
    except Exception as err:  # QhullError: every point on one line
        raise ParameterError(
            f"{where}: the points' currents lie on one line ({' '.join(str(err).split()[:8])}...): "
            "a map needs points spread over (i_d, i_q)."
        ) from err
    psi = interpolate(points, np.column_stack(cols[2:]), targets, smoothing)
    grid = FluxMapGrid(*axes, psi[:, 0].reshape(D.shape), psi[:, 1].reshape(D.shape), source=where)
    return grid, inside


def fill_holes(i_d, i_q, psi_d, psi_q, where: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fill the NaN grid points of a rectangular map (``psi_d, psi_q (n_d, n_q)`` on axes ``i_d (n_d,)``,
    ``i_q (n_q,)``, A and Wb) with the spline through its finite points (module docstring); the finite
    points keep their values. Returns ``(psi_d, psi_q, measured)``, ``measured`` False at the holes."""
    psi_d, psi_q = np.array(psi_d, dtype=float), np.array(psi_q, dtype=float)
    holes = ~(np.isfinite(psi_d) & np.isfinite(psi_q))
    if not holes.any():
        return psi_d, psi_q, ~holes
    D, Q = np.meshgrid(np.asarray(i_d, dtype=float), np.asarray(i_q, dtype=float), indexing="ij")
    known = ~holes
    if known.sum() < 6:
        raise ParameterError(
            f"{where}: only {int(known.sum())} of {holes.size} grid points hold a flux: a map needs at least "
            "6 measured points to fill its holes from."
        )
    points = np.column_stack([D[known], Q[known]])
    filled = interpolate(
        points, np.column_stack([psi_d[known], psi_q[known]]), np.column_stack([D[holes], Q[holes]])
    )
    psi_d[holes], psi_q[holes] = filled[:, 0], filled[:, 1]
    return psi_d, psi_q, known
