"""Where HF injection works on a saturated machine: the part of the MTPA locus, from zero current, where
its saliency signal is strong enough and its angle loop has a lock (NumPy, no JAX; the commands' pre-run
checks and the hybrid's current hand-over read it).

**The signal.** The carrier sees the incremental inductance ``L_inc`` at the operating point; with its
symmetric part's inverse ``G`` (the admittance) the pulsating method's error signal and the rotating
method's negative sequence are both carried by the complex amplitude

    ``Y = (G_dd - G_qq) / 2 + j G_dq``

([`hfi_cross_saturation`][pmsmjax.estimators.hfi_cross_saturation], module docstring): its magnitude is
the signal, its angle twice the lock angle. ``signal`` is ``|Y|`` over its value at zero current
(``|G_dd - G_qq| / 2 = (L_qq - L_dd) / (2 L_dd L_qq)`` there), so the design rule's error-signal amplitude
at no load shrinks by this factor at the operating point, and with it the PLL's gain: a double-pole loop
designed at ``w`` (``kp = 2 w``, ``ki = w^2``) then has ``w_n = w sqrt(signal)`` and damping
``sqrt(signal)``. Where the q path saturates the signal falls towards the point where ``L_qq`` meets
``L_dd`` (the saliency inverts) and rises again past it, now turned towards q: there the injection finds
the q axis, not the d axis. P. Guglielmi, M. Pastorelli, A. Vagati, "Cross-saturation effects in IPM
motors and related impact on sensorless control", IEEE TIA 42(6), 2006, doi:10.1109/TIA.2006.882646
(the saliency's direction and magnitude across the load range).

**The lock.** Two figures per point on the locus:

- ``lock_angle``: the steady angle error of *uncompensated* injection,
  [`predicted_angle_error`][pmsmjax.estimators.hfi_cross_saturation.predicted_angle_error] (``nan``: no
  lock within 90 degrees; the error feeds on itself into the saturated q axis);
- ``loop_gain``: the angle gain of the *compensated* loop
  ([`CrossSaturationCompensated`][pmsmjax.estimators.hfi_cross_saturation.CrossSaturationCompensated],
  which the commands run on a map file). With the corrected estimate ``d`` off the rotor the controller's
  ``i_ref`` lands at ``R(d) i_ref``, the injection locks to the saliency axis there and the correction
  takes the axis at ``i_ref`` out, so the next error is ``F(d) = a(R(d) i_ref) - a(i_ref)``
  (``a`` the [`saliency_angle`][pmsmjax.estimators.hfi_cross_saturation.saliency_angle]); the loop holds
  ``d = 0`` while ``F'(0) < 1``. It is ``F'(0)``, by central differences.

**The region** ([`injection_region`][pmsmjax.estimators.injection_region.injection_region]): on each
branch (motoring, generating) the points from zero current up to the first that fails ``signal >=
fraction`` or the lock (``loop_gain < 1`` for the compensated estimator, a finite ``lock_angle``
without); the region's limits are the smaller branch's ``|torque|`` and ``|i_q|``. The default fraction
[`SIGNAL_FRACTION`][pmsmjax.estimators.injection_region.SIGNAL_FRACTION] = 0.25 (damping 0.5, half the
loop's no-load bandwidth) was set by measurement (benchmarks/hfi_region.py, docs chapter 6): with the
rotor held and the current ramped along the saturated-ipm MTPA locus, both compensated methods hold
within 0.6 degree up to ``i_q`` = 5.4 A and lose the angle at 5.9-6.0 A, where the signal is 0.23 and the
loop gain crosses 1; the 0.25 fraction ends the region at 5.3 A (3.3 N m), before both. Uncompensated,
both lose it at the ``lock_angle``'s end (6.0 A there; 15.2-15.7 A on pm-syrm, where the compensated
ones hold to the current limit).
"""

import dataclasses
import math

import numpy as np

from pmsmjax.controllers.flux_map_loci import mtpa_table
from pmsmjax.estimators.hfi_cross_saturation import predicted_angle_error, saliency_angle
from pmsmjax.machines.flux_map import FluxMapGrid
from pmsmjax.spec.validation import ParameterError, plain

__all__ = [
    "SIGNAL_FRACTION",
    "REGION_POINTS",
    "InjectionRegion",
    "injection_region",
    "saliency_signal",
    "compensated_loop_gain",
    "spec_injection_region",
    "check_injection_load",
]

#: Least saliency signal, as a fraction of its no-load value, the region keeps (module docstring).
SIGNAL_FRACTION = 0.25
#: Current magnitudes per MTPA branch the region is evaluated at (0.25 A apart on saturated-ipm's 25 A).
REGION_POINTS = 101
#: Rotation of the current, rad, for the loop gain's central difference (a 1e-3 A move at 10 A: inside
#: one map cell, far above the interpolant's rounding).
_GAIN_STEP_RAD = 1e-4


def _admittance_signal(L: np.ndarray) -> np.ndarray:
    """``|(G_dd - G_qq) / 2 + j G_dq|`` (1/H), ``G`` the inverse of the symmetric part of ``L (..., 2, 2)``
    (H)."""
    L_dd, L_qq = L[..., 0, 0], L[..., 1, 1]
    M = 0.5 * (L[..., 0, 1] + L[..., 1, 0])
    det = L_dd * L_qq - M * M
    # G = [[L_qq, -M], [-M, L_dd]] / det
    return np.hypot(0.5 * (L_qq - L_dd) / det, M / det)


def saliency_signal(grid: FluxMapGrid, i_dq) -> np.ndarray:
    """The saliency signal at the currents ``i_dq (..., 2)`` A over its value at zero current (module
    docstring), NumPy. Refused (one line naming the map) where the map is not salient at zero current
    (``L_qq <= L_dd``): the signal there points along q, and nothing normalises it."""
    _, L0 = grid.at(0.0, 0.0)
    if not L0[1, 1] > L0[0, 0]:
        raise ParameterError(
            f"{grid.source}: the incremental L_qq = {plain(L0[1, 1])} H at zero current is not above L_dd = "
            f"{plain(L0[0, 0])} H; HF injection has no d axis to find on this machine: use a back-EMF "
            "observer."
        )
    _, L = grid.flux(np.asarray(i_dq, dtype=float))
    return _admittance_signal(L) / _admittance_signal(L0)


def _rotated(angle: float, i: np.ndarray) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.stack([c * i[..., 0] - s * i[..., 1], s * i[..., 0] + c * i[..., 1]], -1)


def compensated_loop_gain(grid: FluxMapGrid, i_dq) -> np.ndarray:
    """``F'(0)`` of the compensated injection loop at the currents ``i_dq (..., 2)`` A (module docstring):
    how much of an angle error comes back after one pass; the loop holds while it is below 1."""
    i = np.asarray(i_dq, dtype=float)
    h = _GAIN_STEP_RAD
    a_plus = saliency_angle(grid.flux(_rotated(h, i))[1], np)
    a_minus = saliency_angle(grid.flux(_rotated(-h, i))[1], np)
    # modulo pi: the axis has no sign
    return ((a_plus - a_minus + 0.5 * np.pi) % np.pi - 0.5 * np.pi) / (2.0 * h)


@dataclasses.dataclass(frozen=True)
class InjectionRegion:
    """Where HF injection works along a map's MTPA locus (module docstring).

    - `i_d`, `i_q`, `torque`: ``(n,)`` the locus, A, A, N m, sorted by ``i_q`` (generating branch first);
    - `signal`: ``(n,)`` saliency signal over its no-load value;
    - `lock_angle`: ``(n,)`` uncompensated lock angle ``th^ - th``, rad (``nan``: no lock);
    - `loop_gain`: ``(n,)`` the compensated loop's angle gain;
    - `inside`: ``(n,)`` the points of the region (contiguous from zero on each branch);
    - `fraction`, `compensated`: the criteria it was cut with;
    - `max_torque_nm`, `max_i_q_a`, `max_current_a`: the region's limits, the smaller branch's (N m, A, and
      the current magnitude there, A; 0 without a region);
    - `limited_by`: what ends it on that branch: ``"signal"``, ``"lock"`` or ``"current limit"``;
    - `source`: the map's source, for messages.
    """

    i_d: np.ndarray
    i_q: np.ndarray
    torque: np.ndarray
    signal: np.ndarray
    lock_angle: np.ndarray
    loop_gain: np.ndarray
    inside: np.ndarray
    fraction: float
    compensated: bool
    max_torque_nm: float
    max_i_q_a: float
    max_current_a: float
    limited_by: str
    source: str

    def serves(self, torque_nm: float) -> bool:
        """Whether a steady load of ``torque_nm`` (N m, either sign) lies inside the region."""
        return abs(torque_nm) <= self.max_torque_nm

    def describe(self) -> str:
        """One phrase: the region's limits and what ends it."""
        return (
            f"HF injection holds up to {self.max_torque_nm:.3g} N m (|i_q| {self.max_i_q_a:.3g} A on the "
            f"MTPA locus; beyond, {_WHY[self.limited_by]})"
        )


_WHY = {
    "signal": "the saliency signal falls below "
    f"{100 * SIGNAL_FRACTION:g} % of its no-load value as the q path saturates",
    "lock": "the injection's angle loop has no lock near d",
    "current limit": "the current limit",
}


def injection_region(
    grid: FluxMapGrid,
    pole_pairs: int,
    current_limit_a: float,
    *,
    fraction: float = SIGNAL_FRACTION,
    compensated: bool = True,
    n_points: int = REGION_POINTS,
) -> InjectionRegion:
    """The region of HF injection on the map ``grid`` (module docstring): its MTPA locus up to
    ``current_limit_a`` (A, peak; ``pole_pairs`` for the torque), ``n_points`` magnitudes per branch, cut
    where the signal falls below ``fraction`` of its no-load value or the lock fails (the compensated
    estimator's loop gain reaches 1 if ``compensated``, else the uncompensated lock angle is ``nan``).
    Refused in one line where the map is not salient at zero current."""
    if not 0.0 < fraction < 1.0:
        raise ParameterError(f"fraction must lie in (0, 1), got {fraction}.")
    table = mtpa_table(grid, pole_pairs, current_limit_a, n_points)
    i_dq = np.stack([table.i_d, table.i_q], -1)
    signal = saliency_signal(grid, i_dq)
    gain = compensated_loop_gain(grid, i_dq)
    n = table.i_q.size
    origin = int(np.argmin(np.abs(table.i_q)))
    lock = np.full(n, np.nan)
    inside = np.zeros(n, bool)
    ends = []
    for order in (range(origin, n), range(origin, -1, -1)):  # motoring, then generating, from zero
        why = "current limit"
        for k in order:
            # a coarse walk (0.25 degree) is enough for the figure; past the first lost lock the rest of
            # the branch is outside anyway, so its (slow, full 90 degree) walks are skipped
            if why == "current limit":
                lock[k] = predicted_angle_error(grid, i_dq[k], step_deg=0.25)[0]
            locked = gain[k] < 1.0 if compensated else np.isfinite(lock[k])
            if why == "current limit" and k != origin and not (signal[k] >= fraction and locked):
                why = "signal" if signal[k] < fraction else "lock"
            if why == "current limit":
                inside[k] = True
        branch = [k for k in order if inside[k]]
        last = branch[-1]
        ends.append((abs(table.torque[last]), abs(table.i_q[last]), table.current[last], why))
    torque_limit, i_q_limit, current_limit, why = min(ends)
    return InjectionRegion(
        table.i_d, table.i_q, table.torque, signal, lock, gain, inside, float(fraction), bool(compensated),
        float(torque_limit), float(i_q_limit), float(current_limit), why, grid.source,
    )  # fmt: skip


def spec_injection_region(spec, **options) -> InjectionRegion:
    """[`injection_region`][pmsmjax.estimators.injection_region.injection_region] of a drive file with a flux
    map (``[motor] flux_map``, ``pole_pairs``, the drive's current limit); refused in one line naming the
    file where the map has no region."""
    if spec.flux_map is None:
        raise ParameterError(
            f"{spec.source}: the injection region is read from a flux map ([motor] flux_map); this drive "
            "file has none."
        )
    try:
        region = injection_region(
            spec.flux_map, int(spec.motor["pole_pairs"]), spec.current_limit_a, **options
        )
    except ParameterError as error:
        raise ParameterError(f"{spec.source}: {error}") from None
    region = dataclasses.replace(region, source=spec.source)  # messages name the drive file
    if region.max_i_q_a <= 0.0:
        raise ParameterError(
            f"{spec.source}: HF injection has no region on this flux map ({_WHY[region.limited_by]} from the "
            "first step of load): use a back-EMF observer."
        )
    return region


def check_injection_load(region: InjectionRegion, load_nm: float, flag: str, estimator: str) -> None:
    """Refuse (one line naming ``flag``) a load ``load_nm`` (N m) beyond the region of ``estimator``."""
    if not region.serves(load_nm):
        raise ParameterError(
            f"{flag} {plain(load_nm)} N m: on {region.source} {estimator} {region.describe()}; give a load "
            f"of at most {region.max_torque_nm:.3g} N m; beyond it only a back-EMF observer (or the "
            "hybrid above its speed band) holds the angle, at speed."
        )
