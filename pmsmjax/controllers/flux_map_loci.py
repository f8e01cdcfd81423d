"""Operating loci of a saturated machine from its flux map, computed at load (NumPy, and SciPy's root
finder for MTPV; no JAX): the maximum-torque-per-ampere (MTPA) locus as a table ``i_d(i_q)`` for motoring
and generating.

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
``i_q``; ``i_q`` rises with ``I`` on each branch (checked), so ``i_d`` is a function of ``i_q``. Every
magnitude is searched at once: the scan is one evaluation of the map on all angles of all magnitudes, and
the Brent search (SciPy's bounded one, written on arrays: `_bounded_minimum`) one evaluation per
step on the magnitudes still searching, so a table is a few dozen NumPy calls (the drive file's checks
build one before every run).
"""

import dataclasses
import math

import numpy as np

from pmsmjax.machines import dq_equations as dq
from pmsmjax.machines.flux_map import FluxMapGrid
from pmsmjax.spec.validation import ParameterError, plain

__all__ = ["MapTorque", "MTPATable", "mtpa_table", "MTPVTable", "mtpv_table", "DEFAULT_POINTS"]

#: Current magnitudes per branch (motoring, generating) of the MTPA sweep.
DEFAULT_POINTS = 61
#: Angles of the coarse scan that brackets the torque maximum at one magnitude.
_SCAN_ANGLES = 48


class MapTorque:
    """NumPy evaluation of a [`FluxMapGrid`][pmsmjax.machines.flux_map.FluxMapGrid]'s interpolant (the
    plant's, [`pmsmjax.machines.flux_map.flux_and_inductance`][pmsmjax.machines.flux_map.flux_and_inductance])
    and torque (the plant's, [`pmsmjax.machines.dq_equations.torque`][pmsmjax.machines.dq_equations.torque]),
    at one point or at many in one call.

    `grid`: the map; `pole_pairs`: ``p``.
    """

    def __init__(self, grid: FluxMapGrid, pole_pairs: int):
        self.grid = grid
        self.pole_pairs = pole_pairs
        self.factor = dq.torque_factor(pole_pairs)

    def flux(self, i_d, i_q) -> tuple[np.ndarray, np.ndarray]:
        """``(psi (..., 2) Wb, L_inc (..., 2, 2) H)`` at the currents ``i_d``, ``i_q`` (A; numbers or arrays
        that broadcast together)."""
        return self.grid.flux(np.stack(np.broadcast_arrays(i_d, i_q), -1))

    def torque(self, i_d, i_q):
        """Air-gap torque ``1.5 p (psi_d i_q - psi_q i_d)``, N m: a float at one point, else an array."""
        psi, _ = self.flux(i_d, i_q)
        torque = dq.torque(self.factor, i_d, i_q, psi[..., 0], psi[..., 1])
        return float(torque) if np.ndim(torque) == 0 else torque


def _cos_sin(angles) -> tuple[np.ndarray, np.ndarray]:
    """``cos``, ``sin`` of ``angles`` by `math` (the platform's libm) element by element: NumPy's SIMD
    sine and cosine may differ from it in the last bit on some builds, and the table's numbers are those
    of the scalar search it replaces."""
    flat = np.asarray(angles, dtype=float).ravel().tolist()
    shape = np.shape(angles)
    return (
        np.array([math.cos(a) for a in flat]).reshape(shape),
        np.array([math.sin(a) for a in flat]).reshape(shape),
    )


def _bounded_minimum(f, a, b, xatol: float, maxfun: int = 500) -> np.ndarray:
    """The minimiser of ``f`` on each interval ``[a[k], b[k]]``, all intervals at once: SciPy's
    ``minimize_scalar(method="bounded")`` (Brent's bounded search, golden sections and parabolic steps;
    Forsythe, Malcolm and Moler, "Computer Methods for Mathematical Computations", 1977, ``fmin``)
    written on arrays, each lane taking the steps and doing the arithmetic SciPy's loop does on it, so each
    result is SciPy's to the bit (tested). A lane stops when SciPy's would; the others go on.

    `f(x, lanes)`: the values at ``x (m,)`` of the lanes ``lanes`` (indices ``(m,)``), one call per step;
    `a`, `b`: ``(n,)`` bounds; `xatol`: absolute tolerance in ``x``; `maxfun`: SciPy's ``maxiter``.
    """
    sqrt_eps = math.sqrt(2.2e-16)
    golden_mean = 0.5 * (3.0 - math.sqrt(5.0))
    a, b = np.array(a, dtype=float), np.array(b, dtype=float)
    fulc = a + golden_mean * (b - a)
    nfc, xf = fulc.copy(), fulc.copy()
    rat, e = np.zeros_like(a), np.zeros_like(a)
    fx = np.asarray(f(xf, np.arange(a.size)), dtype=float)
    ffulc, fnfc = fx.copy(), fx.copy()
    xm = 0.5 * (a + b)
    tol1 = sqrt_eps * np.abs(xf) + xatol / 3.0
    tol2 = 2.0 * tol1
    active = np.abs(xf - xm) > (tol2 - 0.5 * (b - a))
    num = 1
    with np.errstate(divide="ignore", invalid="ignore"):
        while active.any():
            # A parabolic step where the last steps were large enough (|e| > tol1) and the parabola's
            # minimum falls inside the bracket, else a golden section.
            r = (xf - nfc) * (fx - ffulc)
            q = (xf - fulc) * (fx - fnfc)
            p = (xf - fulc) * q - (xf - nfc) * r
            q = 2.0 * (q - r)
            p = np.where(q > 0.0, -p, p)
            q = np.abs(q)
            parabolic = (np.abs(e) > tol1) & (np.abs(p) < np.abs(0.5 * q * e))
            parabolic &= (p > q * (a - xf)) & (p < q * (b - xf))
            rat_p = (p + 0.0) / q
            x_p = xf + rat_p
            near_edge = ((x_p - a) < tol2) | ((b - x_p) < tol2)
            rat_p = np.where(near_edge, tol1 * (np.sign(xm - xf) + ((xm - xf) == 0)), rat_p)
            e_golden = np.where(xf >= xm, a - xf, b - xf)
            e_new = np.where(parabolic, rat, e_golden)
            rat_new = np.where(parabolic, rat_p, golden_mean * e_golden)
            x = xf + (np.sign(rat_new) + (rat_new == 0)) * np.maximum(np.abs(rat_new), tol1)
            lanes = np.flatnonzero(active)
            fu = np.full_like(a, np.nan)
            fu[lanes] = f(x[lanes], lanes)
            num += 1
            # The bracket and the three best points, as SciPy updates them.
            better = fu <= fx
            worse = ~better
            first = worse & ((fu <= fnfc) | (nfc == xf))
            second = worse & ~first & ((fu <= ffulc) | (fulc == xf) | (fulc == nfc))
            new = {
                "a": np.where(better, np.where(x >= xf, xf, a), np.where(x < xf, x, a)),
                "b": np.where(better, np.where(x >= xf, b, xf), np.where(x < xf, b, x)),
                "fulc": np.where(better | first, nfc, np.where(second, x, fulc)),
                "ffulc": np.where(better | first, fnfc, np.where(second, fu, ffulc)),
                "nfc": np.where(better, xf, np.where(first, x, nfc)),
                "fnfc": np.where(better, fx, np.where(first, fu, fnfc)),
                "xf": np.where(better, x, xf),
                "fx": np.where(better, fu, fx),
                "e": e_new,
                "rat": rat_new,
            }
            a, b = np.where(active, new["a"], a), np.where(active, new["b"], b)
            fulc, ffulc = np.where(active, new["fulc"], fulc), np.where(active, new["ffulc"], ffulc)
            nfc, fnfc = np.where(active, new["nfc"], nfc), np.where(active, new["fnfc"], fnfc)
            xf, fx = np.where(active, new["xf"], xf), np.where(active, new["fx"], fx)
            e, rat = np.where(active, new["e"], e), np.where(active, new["rat"], rat)
            xm = 0.5 * (a + b)
            tol1 = sqrt_eps * np.abs(xf) + xatol / 3.0
            tol2 = 2.0 * tol1
            if num >= maxfun:
                break
            active &= np.abs(xf - xm) > (tol2 - 0.5 * (b - a))
    return xf


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


def _best_angles(model: MapTorque, currents: np.ndarray, signs: np.ndarray) -> np.ndarray:
    """Angles ``beta`` in (0, pi) maximising ``signs * T`` at the magnitudes ``currents`` (``(n,)`` each;
    module docstring): the scan and the bounded Brent search of every magnitude at once, a few dozen
    evaluations of the map on arrays."""

    def negative_torque(beta, lanes):
        current, sign = currents[lanes], signs[lanes]
        cos, sin = _cos_sin(beta)
        return -sign * model.torque(current * cos, sign * current * sin)

    lanes = np.arange(currents.size)
    betas = np.linspace(0.0, math.pi, _SCAN_ANGLES + 1)[1:-1]
    values = negative_torque(np.broadcast_to(betas, (lanes.size, betas.size)), lanes[:, None])
    k = np.argmin(values, axis=1)
    step = betas[1] - betas[0]
    lo, hi = np.maximum(betas[k] - step, 1e-9), np.minimum(betas[k] + step, math.pi - 1e-9)
    return _bounded_minimum(negative_torque, lo, hi, xatol=1e-10)


def mtpa_table(
    grid: FluxMapGrid, pole_pairs: int, max_current_a: float, n_points: int = DEFAULT_POINTS
) -> MTPATable:
    """The MTPA locus of ``grid`` up to the current magnitude ``max_current_a`` (A, peak), for both torque
    signs (module docstring), ``n_points`` magnitudes per branch.

    Refuses (one [`ParameterError`][pmsmjax.spec.validation.ParameterError] naming the map) a map whose
    locus does not rise monotonically in ``i_q`` or torque: such a map has no single-valued ``i_d(i_q)``.
    """
    if not max_current_a > 0:
        raise ParameterError(
            f"{grid.source}: the MTPA table needs a positive current limit, got {plain(max_current_a)} A."
        )
    model = MapTorque(grid, pole_pairs)
    magnitudes = np.linspace(0.0, max_current_a, n_points)[1:]
    currents = np.concatenate([magnitudes, magnitudes])
    signs = np.repeat([1.0, -1.0], magnitudes.size)
    beta = _best_angles(model, currents, signs)
    cos, sin = _cos_sin(beta)
    i_d, i_q = currents * cos, signs * currents * sin
    torque = model.torque(i_d, i_q)
    # (i_q, i_d, torque, magnitude); the origin joins the branches
    rows = [(0.0, 0.0, 0.0, 0.0)]
    rows += zip(i_q.tolist(), i_d.tolist(), torque.tolist(), currents.tolist(), strict=True)
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
    from scipy.optimize import brentq  # here: loading SciPy's optimisers takes longer than the table

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
