"""d-axis references of a saturated machine from its flux map: the MTPA and MTPV tables of
[`pmsmjax.controllers.flux_map_loci`][pmsmjax.controllers.flux_map_loci] (computed at load) interpolated in
JAX, and field weakening on them.

**Field weakening**
([`FluxMapFieldWeakening`][pmsmjax.controllers.flux_map_references.FluxMapFieldWeakening]): above base speed
the voltage limit bounds the flux, ``|psi| <~ u_max / w_e``. The voltage-feedback integrator of
[`pmsmjax.controllers.field_weakening`][pmsmjax.controllers.field_weakening] (Kim and Sul 1997) finds the d
current that holds ``|u_dq| = m u_max`` without a model of the voltage limit; on a flux map its base is the
map's MTPA ``i_d(i_q)`` and its floor the map's MTPV ``i_d(i_q)`` (no lower: beyond it the torque per flux
falls) or the current circle, whichever is higher. The FOC's current circle then gives the q axis what is
left.

**Interpolation.** The table's nodes ``(i_q_k, i_d_k)`` are not uniform in ``i_q`` (they are uniform in the
current magnitude), so a node is found by ``searchsorted``; between nodes ``i_d(i_q)`` is the cubic Hermite
polynomial with the node slopes of SciPy's PCHIP (Fritsch and Carlson, "Monotone piecewise cubic
interpolation", SIAM J. Numer. Anal. 17(2), 1980, doi:10.1137/0717021): C1, so the reference and its
derivative in ``i_q`` (which tuning differentiates through) are continuous, and without the overshoot a
cubic spline shows near the origin where the two branches meet. Beyond the table (``|i_q|`` above the
current limit) the end value is held: the FOC's current circle bounds ``i_q`` there anyway.
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from pmsmjax._types import Array
from pmsmjax.controllers.base import AbstractDAxisReference, CurrentLoopContext
from pmsmjax.controllers.field_weakening import voltage_feedback_update
from pmsmjax.controllers.flux_map_loci import MTPATable, mtpa_table, mtpv_table
from pmsmjax.machines.flux_map import FluxMapGrid
from pmsmjax.machines.motor import as_float

__all__ = [
    "TableCurve",
    "FluxMapMTPA",
    "FluxMapFieldWeakening",
    "flux_map_mtpa",
    "flux_map_field_weakening",
]


def _pchip_end_slope(h0, h1, m0, m1) -> float:
    """The end node's slope: the one-sided three-point estimate, kept shape-preserving (zero where it has
    the wrong sign, ``3 m0`` where it overshoots a change of slope sign); Moler, *Numerical Computing with
    MATLAB*, sec. 3.6 (``pchiptx.m``)."""
    d = ((2.0 * h0 + h1) * m0 - h0 * m1) / (h0 + h1)
    if np.sign(d) != np.sign(m0):
        return 0.0
    if np.sign(m0) != np.sign(m1) and abs(d) > 3.0 * abs(m0):
        return 3.0 * m0
    return d


def pchip_slopes(x, y) -> np.ndarray:
    """Node slopes ``dy/dx`` of the shape-preserving piecewise cubic Hermite interpolant (PCHIP; Fritsch and
    Carlson, "Monotone piecewise cubic interpolation", SIAM J. Numer. Anal. 17(2), 1980,
    doi:10.1137/0717021): zero at a local extremum or a flat segment, else the weighted harmonic mean of the
    neighbouring secants ``1/d_k = (w_1/m_{k-1} + w_2/m_k) / (w_1 + w_2)`` with ``w_1 = 2 h_k + h_{k-1}``,
    ``w_2 = h_k + 2 h_{k-1}``; the ends by
    [`_pchip_end_slope`][pmsmjax.controllers.flux_map_references._pchip_end_slope]. The slopes of SciPy's
    ``PchipInterpolator``, in NumPy (this module is loaded by every flux-map drive; SciPy's interpolate
    package takes longer to import than the drive takes to build).

    Args:
        x: ``(n,)`` increasing abscissae, n >= 2.
        y: ``(n,)`` values.

    Returns:
        ``(n,)`` slopes, units of ``y`` per unit of ``x``.
    """
    x, y = np.asarray(x, float), np.asarray(y, float)
    h = np.diff(x)
    m = np.diff(y) / h
    if x.size == 2:
        return np.array([m[0], m[0]])
    d = np.zeros_like(y)
    w1, w2 = 2.0 * h[1:] + h[:-1], h[1:] + 2.0 * h[:-1]
    monotone = (np.sign(m[1:]) == np.sign(m[:-1])) & (m[1:] != 0) & (m[:-1] != 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        harmonic = (w1 / m[:-1] + w2 / m[1:]) / (w1 + w2)
    d[1:-1][monotone] = 1.0 / harmonic[monotone]
    d[0] = _pchip_end_slope(h[0], h[1], m[0], m[1])
    d[-1] = _pchip_end_slope(h[-1], h[-2], m[-1], m[-2])
    return d


class TableCurve(eqx.Module):
    """A C1 curve ``y(x)`` through nodes, cubic Hermite between them (module docstring).

    - `x`: ``(n,)`` strictly increasing nodes; `y`: ``(n,)`` values; `slope`: ``(n,)`` ``dy/dx`` at the
      nodes (units of ``y`` per unit of ``x``).
    """

    x: Array = eqx.field(converter=as_float)
    y: Array = eqx.field(converter=as_float)
    slope: Array = eqx.field(converter=as_float)

    @classmethod
    def pchip(cls, x, y) -> "TableCurve":
        """The curve through ``(x, y)`` with PCHIP node slopes (NumPy arrays, at load)."""
        x, y = np.asarray(x, float), np.asarray(y, float)
        return cls(x, y, pchip_slopes(x, y))

    def __call__(self, x_query) -> Array:
        """``y`` at the scalar ``x_query``, held at the end values outside ``[x[0], x[-1]]``."""
        x = jnp.clip(x_query, self.x[0], self.x[-1])
        k = jnp.clip(jnp.searchsorted(self.x, x, side="right") - 1, 0, self.x.shape[0] - 2)
        x0, h = self.x[k], self.x[k + 1] - self.x[k]
        s = (x - x0) / h
        s2, s3 = s * s, s * s * s
        return (
            (2 * s3 - 3 * s2 + 1) * self.y[k]
            + (s3 - 2 * s2 + s) * h * self.slope[k]
            + (-2 * s3 + 3 * s2) * self.y[k + 1]
            + (s3 - s2) * h * self.slope[k + 1]
        )


class FluxMapMTPA(AbstractDAxisReference):
    """d-axis reference on the flux map's MTPA locus, from last period's ``i_q*`` (like
    [`MTPA`][pmsmjax.controllers.mtpa.MTPA] on the linear model). Stateless.

    `locus`: [`TableCurve`][pmsmjax.controllers.flux_map_references.TableCurve] ``i_d(i_q)``, A (build with
    [`flux_map_mtpa`][pmsmjax.controllers.flux_map_references.flux_map_mtpa]).
    """

    locus: TableCurve

    def init(self, dtype):
        return None

    def step(self, state, id_ref, iq_ref_prev, omega_e, ctx: CurrentLoopContext, current_limit):
        return state, self.locus(iq_ref_prev)


def mtpa_curve(table: MTPATable) -> TableCurve:
    """The table's ``i_d(i_q)`` as a [`TableCurve`][pmsmjax.controllers.flux_map_references.TableCurve]."""
    return TableCurve.pchip(table.i_q, table.i_d)


def flux_map_mtpa(grid: FluxMapGrid, pole_pairs: int, max_current_a: float) -> FluxMapMTPA:
    """[`FluxMapMTPA`][pmsmjax.controllers.flux_map_references.FluxMapMTPA] of ``grid`` up to
    ``max_current_a`` (A) ([`flux_map_loci.mtpa_table`][pmsmjax.controllers.flux_map_loci.mtpa_table])."""
    return FluxMapMTPA(mtpa_curve(mtpa_table(grid, pole_pairs, max_current_a)))


class FluxMapFieldWeakening(AbstractDAxisReference):
    """Voltage-feedback field weakening on the flux map's MTPA (base) and MTPV (floor) loci (module
    docstring). State: ``delta_i_d``, A (<= 0).

    - `mtpa`, `mtpv`: [`TableCurve`][pmsmjax.controllers.flux_map_references.TableCurve] ``i_d(i_q)``, A
      (build with
      [`flux_map_field_weakening`][pmsmjax.controllers.flux_map_references.flux_map_field_weakening]);
    - `bandwidth`: the voltage loop's bandwidth, rad/s;
    - `voltage_margin`: the fraction of ``u_max`` held, in (0, 1].
    """

    mtpa: TableCurve
    mtpv: TableCurve
    bandwidth: Array = eqx.field(converter=as_float)
    voltage_margin: Array = eqx.field(converter=as_float, default=0.95)

    def init(self, dtype):
        return jnp.zeros((), dtype)

    def step(self, state, id_ref, iq_ref_prev, omega_e, ctx: CurrentLoopContext, current_limit):
        base = self.mtpa(iq_ref_prev)
        floor = jnp.maximum(self.mtpv(iq_ref_prev), -current_limit)
        return voltage_feedback_update(
            state, base, jnp.minimum(floor, base), self.bandwidth, self.voltage_margin, omega_e, ctx
        )


def flux_map_field_weakening(
    grid: FluxMapGrid, pole_pairs: int, max_current_a: float, bandwidth: float, voltage_margin: float = 0.95
) -> FluxMapFieldWeakening:
    """[`FluxMapFieldWeakening`][pmsmjax.controllers.flux_map_references.FluxMapFieldWeakening] of ``grid`` up
    to ``max_current_a`` (A): MTPA and MTPV tables at load; `bandwidth` rad/s, `voltage_margin` of
    ``u_max``."""
    mtpa = mtpa_table(grid, pole_pairs, max_current_a)
    away = mtpa.i_q != 0.0  # MTPV is undefined without torque
    mtpv = mtpv_table(grid, pole_pairs, mtpa.i_q[away], mtpa.i_d[away])
    return FluxMapFieldWeakening(
        mtpa_curve(mtpa), TableCurve.pchip(mtpv.i_q, mtpv.i_d), bandwidth, voltage_margin
    )
