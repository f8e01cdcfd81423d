"""Operating loci of a saturated machine from its flux map, computed at load (NumPy and SciPy, no JAX):
the maximum-torque-per-ampere (MTPA) locus as a table ``i_d(i_q)`` for motoring and generating.

The torque is the map's, ``T = 1.5 p (psi_d(i) i_q - psi_q(i) i_d)`` (amplitude-invariant dq, peak values),
with ``psi`` the map's bicubic Hermite interpolant ([`pmsmjax.machines.flux_map`][pmsmjax.machines.flux_map]),
so saturation and cross-saturation move the locus; on a linear map it is the closed form of
[`pmsmjax.controllers.mtpa`][pmsmjax.controllers.mtpa].

**MTPA** (the book, ch. 3, for a linear machine; for a flux map e.g. Bianchi and Bolognani, "Parameters and
volt-ampere ratings of a synchronous motor drive for flux-weakening applications", IEEE Trans. Power
Electron. 12(5), 1997; tables of MTPA and MTPV from a measured map as here: Awan, Song, Saarakkala and
Hinkkanen, "Optimal torque control of saturated synchronous motors: plug-and-play method", IEEE Trans.
Ind. Appl. 54(6), 2018): the least current magnitude for each torque. Along the
locus the torque rises monotonically with the magnitude, so this is the same set of points as the most
torque for each magnitude ``I``, which is a one-dimensional search over the current angle: for each ``I``
of a sweep ``0..I_max`` the angle ``beta`` (``i_d = I cos beta``, ``i_q = +-I sin beta``) that maximises
``+-T`` (motoring ``+``, generating ``-``), by a coarse scan over ``(0, pi)`` that brackets the maximum and
a bounded Brent search inside the bracket (the torque at fixed ``I`` has one maximum per sign for an
interior-PM map; the scan guards against a flat start). The table is the union of both signs, sorted by
``i_q``; ``i_q`` rises with ``I`` on each branch (checked), so ``i_d`` is a function of ``i_q``.
"""

import dataclasses
import math

import numpy as np
from scipy.optimize import brentq, minimize_scalar

from pmsmjax.checks.validation import ParameterError, plain
from pmsmjax.machines.flux_map import FluxMapGrid, flux_and_inductance

__all__ = ["MapTorque", "MTPATable", "mtpa_table", "MTPVTable", "mtpv_table", "DEFAULT_POINTS"]

#: Current magnitudes per branch (motoring, generating) of the MTPA sweep.
DEFAULT_POINTS = 61
#: Angles of the coarse scan that brackets the torque maximum at one magnitude.
_SCAN_ANGLES = 48


class MapTorque:
    """NumPy evaluation of a [`FluxMapGrid`][pmsmjax.machines.flux_map.FluxMapGrid]'s interpolant at single
    points, its coefficients computed once (``FluxMapGrid.at`` recomputes them per call).

    `grid`: the map; `pole_pairs`: ``p``.
    """

    def __init__(self, grid: FluxMapGrid, pole_pairs: int):
        self.grid = grid
        self.pole_pairs = pole_pairs
        self._coefficients = grid.coefficients()

    def flux(self, i_d: float, i_q: float) -> tuple[np.ndarray, np.ndarray]:
        """``(psi (2,) Wb, L_inc (2, 2) H)`` at ``(i_d, i_q)`` A."""
        g = self.grid
        i = np.array([i_d, i_q], dtype=float)
        return flux_and_inductance(self._coefficients, g.lower, g.step, g.upper, i, np)

    def torque(self, i_d: float, i_q: float) -> float:
        """Air-gap torque ``1.5 p (psi_d i_q - psi_q i_d)``, N m."""
        psi, _ = self.flux(i_d, i_q)
        return 1.5 * self.pole_pairs * float(psi[0] * i_q - psi[1] * i_d)


@dataclasses.dataclass(frozen=True)
class MTPATable:
    """The MTPA locus, sorted by ``i_q`` (generating branch first, then the origin, then motoring).

    - `i_q`, `i_d`: ``(n,)`` currents on the locus, A (``i_q`` strictly increasing);
    - `torque`: ``(n,)`` the map's torque there, N m (increasing with ``i_q``);
    - `current`: ``(n,)`` the magnitude ``|i_dq|``, A.
    """

    i_q: np.ndarray
    i_d: np.ndarray
    torque: np.ndarray
    current: np.ndarray

    def current_for_torque(self, torque_nm: float) -> float:
        """The least current magnitude (A) that gives ``torque_nm`` (N m), interpolated on the table."""
        return float(np.interp(torque_nm, self.torque, self.current))

    def point_for_torque(self, torque_nm: float) -> tuple[float, float]:
        """``(i_d, i_q)`` A of the MTPA point giving ``torque_nm`` (N m), interpolated on the table."""
        return float(np.interp(torque_nm, self.torque, self.i_d)), float(
            np.interp(torque_nm, self.torque, self.i_q)
        )

    def torque_at_current(self, current_a: float, motoring: bool = True) -> float:
        """The most torque magnitude (N m) the current magnitude ``current_a`` (A) gives on one branch."""
        branch = self.i_q >= 0 if motoring else self.i_q <= 0
        order = np.argsort(self.current[branch])
        return float(np.interp(current_a, self.current[branch][order], np.abs(self.torque[branch][order])))


def _best_angle(model: MapTorque, current: float, sign: float) -> float:
    """Angle ``beta`` in (0, pi) maximising ``sign * T`` at magnitude ``current`` (module docstring)."""

    def negative_torque(beta):
        return -sign * model.torque(current * math.cos(beta), sign * current * math.sin(beta))

    betas = np.linspace(0.0, math.pi, _SCAN_ANGLES + 1)[1:-1]
    values = np.array([negative_torque(b) for b in betas])
    k = int(np.argmin(values))
    step = betas[1] - betas[0]
    lo, hi = max(betas[k] - step, 1e-9), min(betas[k] + step, math.pi - 1e-9)
    result = minimize_scalar(negative_torque, bounds=(lo, hi), method="bounded", options={"xatol": 1e-10})
    return float(result.x)


def mtpa_table(
    grid: FluxMapGrid, pole_pairs: int, max_current_a: float, n_points: int = DEFAULT_POINTS
) -> MTPATable:
    """The MTPA locus of ``grid`` up to the current magnitude ``max_current_a`` (A, peak), for both torque
    signs (module docstring), ``n_points`` magnitudes per branch.

    Refuses (one [`ParameterError`][pmsmjax.checks.validation.ParameterError] naming the map) a map whose
    locus does not rise monotonically in ``i_q`` or torque: such a map has no single-valued ``i_d(i_q)``.
    """
    if not max_current_a > 0:
        raise ParameterError(
            f"{grid.source}: the MTPA table needs a positive current limit, got {plain(max_current_a)} A."
        )
    model = MapTorque(grid, pole_pairs)
    currents = np.linspace(0.0, max_current_a, n_points)[1:]
    rows = [(0.0, 0.0, 0.0, 0.0)]  # (i_q, i_d, torque, magnitude): the origin joins the branches
    for sign in (1.0, -1.0):
        for current in currents:
            beta = _best_angle(model, current, sign)
            i_d, i_q = current * math.cos(beta), sign * current * math.sin(beta)
            rows.append((i_q, i_d, model.torque(i_d, i_q), current))
    i_q, i_d, torque, magnitude = np.array(sorted(rows)).T
    for name, values in (("i_q", i_q), ("torque", torque)):
        if np.any(np.diff(values) <= 0):
            k = int(np.argmax(np.diff(values) <= 0))
            raise ParameterError(
                f"{grid.source}: the MTPA locus's {name} does not rise with the current near i_d = "
                f"{i_d[k]:.3g} A, i_q = {i_q[k]:.3g} A: the map is not a motor's up to "
                f"{plain(max_current_a)} A; check its signs or lower the current limit."
            )
    return MTPATable(i_q, i_d, torque, magnitude)


def _mtpv_condition(model: MapTorque, i_d: float, i_q: float) -> float:
    """``dT/di_d dF/di_q - dT/di_q dF/di_d`` with ``F = |psi|^2 / 2`` (N m Wb^2 / A^2 up to the factor
    ``1.5 p``): zero where the torque gradient is parallel to the flux magnitude's, i.e. on MTPV."""
    psi, L = model.flux(i_d, i_q)
    torque_d = L[0, 0] * i_q - L[1, 0] * i_d - psi[1]  # dT/di_d / (1.5 p)
    torque_q = psi[0] + L[0, 1] * i_q - L[1, 1] * i_d  # dT/di_q / (1.5 p)
    flux_d, flux_q = L.T @ psi  # grad |psi|^2 / 2
    return float(torque_d * flux_q - torque_q * flux_d)


@dataclasses.dataclass(frozen=True)
class MTPVTable:
    """The MTPV (maximum torque per flux, the book, ch. 3 for a linear machine) locus of a flux map, as
    the most negative useful ``i_d`` for each ``i_q``: beyond it (more negative ``i_d``) the torque per
    flux falls, so field weakening gains nothing.

    - `i_q`, `i_d`: ``(n,)`` currents, A (``i_q`` strictly increasing, both signs);
    - `inside`: ``(n,)`` bool, False where the map has no MTPV point between its lower ``i_d`` edge and
      the MTPA locus (``i_d`` is then that edge: the current limit binds first).
    """

    i_q: np.ndarray
    i_d: np.ndarray
    inside: np.ndarray


def mtpv_table(grid: FluxMapGrid, pole_pairs: int, i_q, i_d_upper) -> MTPVTable:
    """The MTPV locus at the currents ``i_q (n,)`` (A, increasing, nonzero): for each the root in ``i_d`` of
    the parallel-gradient condition between the map's lower ``i_d`` edge and ``i_d_upper (n,)`` (A, the
    MTPA ``i_d`` there; between the two the flux magnitude at constant torque falls, then rises), by
    Brent's method."""
    model = MapTorque(grid, pole_pairs)
    rows = []
    for q, upper in zip(np.asarray(i_q, float), np.asarray(i_d_upper, float), strict=True):
        f = lambda i_d, q=q: _mtpv_condition(model, i_d, q)  # noqa: E731
        lo = float(grid.i_d[0])
        if f(lo) * f(upper) < 0:
            rows.append((q, brentq(f, lo, upper, xtol=1e-10), True))
        else:
            rows.append((q, lo, False))
    i_q, i_d, inside = (np.array(c) for c in zip(*rows, strict=True))
    return MTPVTable(i_q, i_d, inside.astype(bool))
