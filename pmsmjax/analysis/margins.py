"""Stability margins of a drive's loop from its linearised sampled-data loop transfer ``L(e^{j w Ts})``.

The figures MATLAB's Field Oriented Control Autotuner tunes each loop to (bandwidth and phase margin,
https://www.mathworks.com/help/mcb/ref/fieldorientedcontrolautotuner.html), plus the gain margin and the
sensitivity peak of Åström and Murray (*Feedback Systems*, 2nd ed., 2021: stability margins, and the maximum
sensitivity as the inverse of the shortest distance to -1):

- **crossover** ``f_c`` (Hz): where ``|L| = 1``; the **phase margin** ``PM = 180 deg + arg L(f_c)``, taken
  as the angle between ``L(f_c)`` and -1, ``|arg(-L(f_c))|`` in [0, 180] deg, the smallest over every
  crossover below the Nyquist frequency (a compliant shaft's resonance can lift ``|L|`` above 1 again, where
  ``arg L`` may lie anywhere); whether the closed loop is stable at all is the spectral radius's question
  ([`LinearDrive.spectral_radius`][pmsmjax.analysis.loop_linearisation.LinearDrive.spectral_radius]);
- **gain margin** ``GM = -20 log10 |L(f_180)|`` dB at every phase crossover ``arg L = -180 deg`` (``L``
real and
  negative), the smallest; ``inf`` without a phase crossover below Nyquist;
- **sensitivity peak** ``M_s = max |S|``, ``S = 1/(1 + L)``: the inverse of the shortest distance from
``L`` to
  -1 (``M_s <= 2`` guarantees ``GM >= 6 dB`` and ``PM >= 29 deg``);
- **bandwidth** (Hz): the lowest frequency where the complementary sensitivity ``|T| = |1 - S|`` falls below
  -3 dB.

The frequencies lie on a logarithmic grid up to just below the Nyquist frequency ``1/(2 Ts)``; each crossing
is located by interpolating ``log|L|`` (or ``Im L``) in ``log f`` between grid points and ``L`` is evaluated
again exactly there, so the margins are differentiable in the drive's parameters (through ``A``, ``B``, ``C``,
``D``) almost everywhere: the grid's bracketing is piecewise constant, the values are smooth.
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from pmsmjax._types import Array
from pmsmjax.analysis.loop_linearisation import LinearDrive

__all__ = ["LoopMargins", "loop_margins", "frequency_grid", "drive_margins", "margins_line"]

#: Default grid: points and lowest frequency, Hz.
GRID_POINTS = 400
GRID_LOW_HZ = 0.5


class LoopMargins(eqx.Module):
    """A loop's margins (module docstring); scalars, ``inf`` where a crossing does not occur.

    Attributes:
        crossover_hz: Lowest gain crossover ``|L| = 1``, Hz.
        phase_margin_deg: Smallest phase margin over the gain crossovers, deg.
        gain_margin_db: Smallest gain margin over the phase crossovers, dB.
        sensitivity_peak: ``max |S|`` (1).
        sensitivity_peak_hz: Where it occurs, Hz.
        bandwidth_hz: Lowest frequency of ``|T|`` below -3 dB, Hz.
    """

    crossover_hz: Array
    phase_margin_deg: Array
    gain_margin_db: Array
    sensitivity_peak: Array
    sensitivity_peak_hz: Array
    bandwidth_hz: Array

    def as_dict(self) -> dict:
        """Plain floats by name (``None`` for a crossing that does not occur), for JSON."""
        out = {}
        for name in (
            "crossover_hz",
            "phase_margin_deg",
            "gain_margin_db",
            "sensitivity_peak",
            "sensitivity_peak_hz",
            "bandwidth_hz",
        ):
            v = float(np.asarray(getattr(self, name)))
            out[name] = v if np.isfinite(v) else None
        return out


def frequency_grid(Ts: float, points: int = GRID_POINTS, low_hz: float = GRID_LOW_HZ) -> np.ndarray:
    """``(points,)`` logarithmic grid from ``low_hz`` to 0.499 / ``Ts`` (just below Nyquist), Hz."""
    return np.logspace(np.log10(low_hz), np.log10(0.499 / Ts), points)


def _safe_div(a, b):
    ok = jnp.abs(b) > 0
    return jnp.where(ok, a / jnp.where(ok, b, 1.0), 0.5)


def _crossings(logf, g, mask, evaluate):
    """Where ``g`` (on the grid) changes sign between neighbours flagged by ``mask``: the interpolated
    ``log f`` and ``evaluate(f)`` there, ``(K-1,)`` each (meaningless where ``mask`` is False)."""
    frac = jnp.clip(_safe_div(g[:-1], g[:-1] - g[1:]), 0.0, 1.0)
    lf = logf[:-1] + frac * (logf[1:] - logf[:-1])
    f = jnp.exp(lf)
    return f, evaluate(f)


def loop_margins(lin: LinearDrive, loop: str, freq_hz=None) -> LoopMargins:
    """The margins of ``loop`` (``"current"`` or ``"speed"``) of the linearised drive ``lin``.

    Args:
        lin: The drive linearised at an operating point
            ([`linearise`][pmsmjax.analysis.loop_linearisation.linearise]).
        loop: Which loop (its break point and the other loop's state: see
            [`LinearDrive.sensitivity`][pmsmjax.analysis.loop_linearisation.LinearDrive.sensitivity]).
        freq_hz: ``(K,)`` increasing grid, Hz, below Nyquist; default
            [`frequency_grid`][pmsmjax.analysis.margins.frequency_grid].

    Returns:
        The [`LoopMargins`][pmsmjax.analysis.margins.LoopMargins] (traceable: jit, vmap and grad apply).
    """
    f = jnp.asarray(frequency_grid(lin.Ts) if freq_hz is None else freq_hz, lin.A.dtype)
    logf = jnp.log(f)
    S = lin.sensitivity(loop, f)
    L = 1.0 / S - 1.0
    exact = lambda ff: 1.0 / lin.sensitivity(loop, ff) - 1.0
    inf = jnp.asarray(jnp.inf, lin.A.dtype)

    # gain crossovers
    gain = jnp.log(jnp.abs(L))
    cross = (gain[:-1] >= 0) != (gain[1:] >= 0)
    f_c, L_c = _crossings(logf, gain, cross, exact)
    pm = jnp.abs(jnp.degrees(jnp.angle(-L_c)))
    phase_margin = jnp.min(jnp.where(cross, pm, inf))
    crossover = jnp.min(jnp.where(cross, f_c, inf))

    # phase crossovers: Im L changes sign where Re L < 0
    im = jnp.imag(L)
    flip = ((im[:-1] >= 0) != (im[1:] >= 0)) & (jnp.real(L[:-1]) < 0) & (jnp.real(L[1:]) < 0)
    _, L_p = _crossings(logf, im, flip, exact)
    gm = -20.0 * jnp.log10(jnp.where(flip, jnp.abs(L_p), 1.0))
    gain_margin = jnp.min(jnp.where(flip, gm, inf))

    # sensitivity peak and bandwidth (|T| below 1/sqrt(2))
    s_abs = jnp.abs(S)
    k = jnp.argmax(s_abs)
    t_db = jnp.abs(1.0 - S) * np.sqrt(2.0) - 1.0
    below = (t_db[:-1] >= 0) & (t_db[1:] < 0)
    f_b, _ = _crossings(logf, t_db, below, lambda ff: ff)
    bandwidth = jnp.min(jnp.where(below, f_b, inf))
    return LoopMargins(crossover, phase_margin, gain_margin, s_abs[k], f[k], bandwidth)


def drive_margins(drive, speed_m: float, load_nm: float, where: str = "") -> dict:
    """Both loops' margins at the steady state of ``speed_m`` (mechanical rad/s) and ``load_nm`` (N m),
    for a report (summary.json, result.json): ``{"operating_point", "spectral_radius", "stable",
    "fixed_point_residual", "current": {...}, "speed": {...}}``, the loops' entries
    [`LoopMargins.as_dict`][pmsmjax.analysis.margins.LoopMargins.as_dict].

    Raises:
        ParameterError: For a drive or an operating point outside the linearisation's scope
            ([`check_linearisable`][pmsmjax.analysis.loop_linearisation.check_linearisable]; ``where`` names
            the operating point's source in the message).
    """
    from pmsmjax.analysis.loop_linearisation import check_linearisable

    check_linearisable(drive, speed_m, load_nm, where=where)
    dtype = drive.machine.motor.R.dtype
    lin, margins = _margins(drive, jnp.asarray(speed_m, dtype), jnp.asarray(load_nm, dtype))
    rho = float(lin.spectral_radius())
    out = {
        "operating_point": {"speed_rad_s": float(speed_m), "load_nm": float(load_nm)},
        "spectral_radius": rho,
        "stable": rho < 1.0,
        "fixed_point_residual": float(lin.residual),
    }
    out.update({loop: m.as_dict() for loop, m in margins.items()})
    return out


@eqx.filter_jit
def _margins(drive, speed_m, load_nm):
    from pmsmjax.analysis.loop_linearisation import LOOPS, linearise_traced

    lin = linearise_traced(drive, speed_m, load_nm)
    return lin, {loop: loop_margins(lin, loop) for loop in LOOPS}


def margins_line(entry: dict) -> str:
    """One console line of [`drive_margins`][pmsmjax.analysis.margins.drive_margins]'s report."""
    parts = []
    for loop in ("current", "speed"):
        m = entry[loop]
        fmt = lambda v, spec: "n/a" if v is None else format(v, spec)  # noqa: E731
        parts.append(
            f"{loop} loop: crossover {fmt(m['crossover_hz'], '.4g')} Hz, "
            f"PM {fmt(m['phase_margin_deg'], '.1f')} deg, GM {fmt(m['gain_margin_db'], '.1f')} dB, "
            f"Ms {fmt(m['sensitivity_peak'], '.2f')}"
        )
    stable = "stable" if entry["stable"] else "UNSTABLE"
    return f"margins ({stable}, spectral radius {entry['spectral_radius']:.4f}): " + "; ".join(parts)
