"""Reference and load profiles as array pytrees (vmappable, differentiable in their values and times).

A [`Profile`][pmsmjax.scenarios.Profile] is piecewise: breakpoints ``times (K,)`` s with ``values (K,)``; on
``[times[k], times[k+1])`` the value is held (``linear[k] = 0``) or interpolated linearly towards
``values[k+1]`` (``linear[k] = 1``). Before ``times[0]`` the first value holds, after the last breakpoint
the last value. Steps, ramps, reversals and arbitrary staircases are all of this form, so a batch of
different scenarios is one stacked pytree (pad with [`stack_scenarios`][pmsmjax.scenarios.stack_scenarios]).
"""

from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from pmsmjax._types import Array
from pmsmjax.machines.motor import as_float
from pmsmjax.spec.validation import ParameterError, check_finite, check_positive, is_concrete


class Profile(eqx.Module):
    """Piecewise hold/linear profile of a scenario signal against time.

    Each segment from breakpoint ``k`` to ``k + 1`` holds ``values[k]`` (``linear[k] == 0``) or
    interpolates to ``values[k + 1]`` (``linear[k] == 1``); the last value is held.

    Args:
        times: ``(K,)`` (or ``(batch, K)``) non-decreasing breakpoint times, s.
        values: ``(K,)`` (or ``(batch, K)``) values at the breakpoints, in the signal's unit.
        linear: ``(K,)`` (or ``(batch, K)``) 1 where the segment from the breakpoint is linear, 0 where held.

    Raises:
        ParameterError: For arrays of different shapes, non-finite values or unsorted times.
    """

    times: Array = eqx.field(converter=as_float)
    values: Array = eqx.field(converter=as_float)
    linear: Array = eqx.field(converter=as_float)

    def __check_init__(self):
        if not all(is_concrete(x) for x in (self.times, self.values, self.linear)):
            return
        if not (self.times.shape == self.values.shape == self.linear.shape) or self.times.ndim < 1:
            raise ParameterError(
                "Profile times, values and linear must have the same shape (K,), got "
                f"{self.times.shape}, {self.values.shape}, {self.linear.shape}."
            )
        check_finite("Profile.times", self.times, "s")
        check_finite("Profile.values", self.values)
        if np.any(np.diff(np.asarray(self.times), axis=-1) < 0):
            raise ParameterError("Profile.times must be non-decreasing: sort the breakpoints by time.")

    @staticmethod
    def constant(value) -> "Profile":
        """``value`` at all times."""
        return Profile([0.0], [value], [0.0])

    @staticmethod
    def step(time_s, before, after) -> "Profile":
        """``before`` until ``time_s``, then ``after``.

        Args:
            time_s: Time of the step, s.
            before: Value before the step.
            after: Value from the step on.
        """
        return Profile([0.0, time_s], [before, after], [0.0, 0.0])

    @staticmethod
    def ramp(start_s, end_s, start_value, end_value) -> "Profile":
        """``start_value`` until ``start_s``, linear to ``end_value`` at ``end_s``, then held.

        Args:
            start_s: Start of the ramp, s.
            end_s: End of the ramp, s.
            start_value: Value until the ramp starts.
            end_value: Value from the ramp's end on.
        """
        return Profile([0.0, start_s, end_s], [start_value, start_value, end_value], [0.0, 1.0, 0.0])

    @staticmethod
    def piecewise(times, values, interpolation: str = "hold") -> "Profile":
        """Breakpoints with one interpolation for all segments.

        Args:
            times: ``(K,)`` breakpoint times, s (non-decreasing).
            values: ``(K,)`` values at the breakpoints.
            interpolation: ``"hold"`` or ``"linear"``.

        Raises:
            ParameterError: For another interpolation.
        """
        if interpolation not in ("hold", "linear"):
            raise ParameterError(f"interpolation must be 'hold' or 'linear', got {interpolation!r}.")
        times = np.asarray(times, dtype=float)
        flag = 1.0 if interpolation == "linear" else 0.0
        return Profile(times, values, np.full(times.shape, flag))

    def __call__(self, t) -> Array:
        """Value at time ``t`` (s, scalar)."""
        return _evaluate(self.times, self.values, self.linear, t)

    def sample(self, t: Array) -> Array:
        """Values at the times ``t``.

        Args:
            t: ``(N,)`` times, s.

        Returns:
            ``(N,)`` values.
        """
        return jax.vmap(self)(t)

    def sample_periods(self, n: int, Ts: float) -> Array:
        """Values at the period starts ``k Ts``, ``k = 0..n-1``, by integer period index.

        Breakpoints are placed on the period grid as ``times / Ts`` periods, snapped to the nearest whole
        period when within rounding (``1e-3`` period plus a few ulps), so a load step at 0.2352 s with
        ``Ts = 1e-4`` s acts from period 2352 on in float32 too (comparing float times ``k Ts`` would put it
        one period late). The snap passes gradients straight through (``x + stop_gradient(round(x) - x)``).

        Args:
            n: Number of periods.
            Ts: Control period, s.

        Returns:
            ``(n,)`` values.
        """
        k = jnp.arange(n, dtype=self.times.dtype)
        position = self.times / Ts
        nearest = jnp.round(position)
        tol = 1e-3 + 8.0 * jnp.finfo(position.dtype).eps * jnp.abs(position)
        snap = jnp.where(jnp.abs(position - nearest) <= tol, nearest - position, 0.0)
        grid = position + jax.lax.stop_gradient(snap)
        return jax.vmap(lambda x: _evaluate(grid, self.values, self.linear, x))(k)

    def padded(self, K: int) -> "Profile":
        """The same profile with ``K`` breakpoints (the last one repeated, held).

        Args:
            K: Breakpoint count, at least the profile's own.

        Raises:
            ParameterError: When the profile has more than ``K`` breakpoints.
        """
        n = self.times.shape[-1]
        if n > K:
            raise ParameterError(f"cannot pad a profile of {n} breakpoints to {K}.")
        pad = lambda x, fill: jnp.concatenate([x, jnp.full((K - n,), fill, x.dtype)])
        return Profile(
            pad(self.times, self.times[-1]),
            pad(self.values, self.values[-1]),
            pad(self.linear, 0.0),
        )


def _evaluate(times: Array, values: Array, linear: Array, t) -> Array:
    """A profile's value at ``t`` (in the units of ``times``): held or interpolated segment by segment."""
    K = times.shape[-1]
    k = jnp.clip(jnp.searchsorted(times, t, side="right") - 1, 0, K - 1)
    k1 = jnp.minimum(k + 1, K - 1)
    t0, t1 = times[k], times[k1]
    span = t1 - t0
    has_span = span > 0
    frac = jnp.where(has_span, (t - t0) / jnp.where(has_span, span, 1.0), 0.0)
    frac = jnp.clip(frac, 0.0, 1.0)
    return values[k] + linear[k] * frac * (values[k1] - values[k])


def _zero() -> Profile:
    return Profile.constant(0.0)


class Scenario(eqx.Module):
    """What the drive is asked to do over ``duration_s``.

    Args:
        duration_s: Simulated time, s (static: it sets the number of control periods).
        speed_ref: Speed reference, mechanical rad/s; with ``mechanics="imposed"`` it is the speed a
            dynamometer imposes on the shaft.
        load_torque: Load torque, N m (opposes positive speed when positive).
        id_ref: d-axis current reference, A (0 for i_d = 0 control).
        iq_ref: q-axis current reference, A (used by controllers in current mode).
        measured_iq_perturbation: A, added to the q current the controller measures (the current loop's
            break point, for a loop-response measurement,
            [`pmsmjax.analysis.loop_sweep`][pmsmjax.analysis.loop_sweep]); None (default): none, and the
            simulation is the same program as without the field.
        iq_ref_perturbation: A, added to the q-current reference after the speed controller (the speed
            loop's break point); None (default): none.
    """

    duration_s: float = eqx.field(static=True)
    speed_ref: Profile = eqx.field(default_factory=_zero)
    load_torque: Profile = eqx.field(default_factory=_zero)
    id_ref: Profile = eqx.field(default_factory=_zero)
    iq_ref: Profile = eqx.field(default_factory=_zero)
    measured_iq_perturbation: Profile | None = None
    iq_ref_perturbation: Profile | None = None

    def __check_init__(self):
        check_positive("Scenario.duration_s", self.duration_s, "s")

    def n_periods(self, Ts: float) -> int:
        """Number of control periods of length ``Ts`` in the scenario (rounded to nearest).

        Args:
            Ts: Control period, s.
        """
        return int(round(self.duration_s / Ts))


def stack_scenarios(scenarios: Sequence[Scenario]) -> Scenario:
    """Stack scenarios of equal duration into one batched Scenario.

    Profiles with fewer breakpoints are padded (their last value held) to the longest one's.

    Args:
        scenarios: Scenarios of one ``duration_s``.

    Returns:
        A [`Scenario`][pmsmjax.scenarios.Scenario] whose profile leaves have a leading axis of one row per
        scenario.

    Raises:
        ParameterError: For no scenarios or different durations.
    """
    if len(scenarios) == 0:
        raise ParameterError("stack_scenarios needs at least one scenario.")
    durations = {s.duration_s for s in scenarios}
    if len(durations) != 1:
        raise ParameterError(
            f"scenarios in one batch must share duration_s (it fixes the scan length), got {durations}."
        )
    padded = []
    fields = ["speed_ref", "load_torque", "id_ref", "iq_ref"]
    for field in ("measured_iq_perturbation", "iq_ref_perturbation"):  # optional: kept where any has it
        if any(getattr(s, field) is not None for s in scenarios):
            fields.append(field)
    for field in fields:
        profiles = [getattr(s, field) or _zero() for s in scenarios]
        K = max(p.times.shape[-1] for p in profiles)
        padded.append([p.padded(K) for p in profiles])
    rows = [
        Scenario(scenarios[0].duration_s, **{f: padded[j][i] for j, f in enumerate(fields)})
        for i in range(len(scenarios))
    ]
    return jax.tree.map(lambda *xs: jnp.stack(xs), *rows)
