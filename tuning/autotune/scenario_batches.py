"""Reproducible batches of speed/load scenarios for tuning (a train batch and a held-out batch).

Every scenario of a batch is simulated over the same horizon (the scan length is shared); each has its
own duration inside it, and objectives ignore what comes after it
([`ScenarioBatch.active`][tuning.autotune.scenario_batches.ScenarioBatch.active]).
"""

from collections.abc import Sequence

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from pmsmjax import Profile, Scenario, stack_scenarios
from pmsmjax.presets.book_constants import BOOK_TS
from pmsmjax.spec.validation import ParameterError
from pmsmjax.units import rpm_to_rad_s

KINDS = ("step", "reversal", "ramp")
#: Time the observer batches ([`tuning.autotune.observers`][tuning.autotune.observers],
#: [`tuning.autotune.hfi_tuning`][tuning.autotune.hfi_tuning]) run on the sensor before the observer takes
#: over, s (each observer converges within a few ms at speed).
WARMUP_S = 0.02


class ScenarioBatch(eqx.Module):
    """A stacked batch of scenarios with per-scenario duration and load-step time.

    - `scenarios`: a batched [`pmsmjax.Scenario`][pmsmjax.scenarios.Scenario] (leading axis = scenario),
      horizon ``horizon_s``.
    - `duration_s`: ``(B,)`` each scenario's own duration, s (objectives ignore later samples).
    - `load_time_s`: ``(B,)`` time of the load change, s (the speed-step window ends there).
    - `kind`: the kind of each scenario (``step``, ``reversal``, ``ramp``), for reports.
    - `plant_scale`: ``{motor parameter: (B,) factor}``: each scenario runs a plant whose parameter is
      the drive's times this factor (robust tuning over parameter spreads; empty for the nominal plant).
      The controller's own motor model stays nominal, as it would on a real drive; ``u_dc_v`` scales the
      bridge's DC link, which the controller measures (its voltage limit follows); ``initial_k`` and
      ``ambient_k`` scale a warm motor's initial winding and ambient temperatures (kelvin,
      [`pmsmjax.machines.thermal.WindingThermal`][pmsmjax.machines.thermal.WindingThermal]);
      ``current_offset_a`` (``(B, 3)``, A, *added* to each current sensor's offset: an offset's nominal may
      be zero) and ``current_gain`` (``(B, 3)`` factors of each sensor's gain) draw the current sensors
      ([`pmsmjax.estimators.current_sensors.CurrentSensors`][pmsmjax.estimators.current_sensors.CurrentSensors];
      the first ``k`` columns serve ``k`` sensors).
    - `initial_speed_m`, `initial_theta_e`: ``(B,)`` mechanical speed (rad/s) and electrical angle (rad)
      each scenario starts at (``None``: at rest, angle 0); the observer batches of
      [`tuning.autotune.observers`][tuning.autotune.observers] start at speed.
    - `observe_from_s`: ``(B,)`` start of the window of the angle-error metric, s (``None``: from 0); the
      observer batches start it when the observer takes over from the sensor.
    - `angle_modulo`: static, the period of the angle-error metric, electrical rad: ``2 pi``, or ``pi`` for
      the HF-injection estimators, which find the d axis modulo pi (their batches,
      [`tuning.autotune.hfi_tuning.make_injection_batch`][tuning.autotune.hfi_tuning.make_injection_batch]).
    """

    scenarios: Scenario
    duration_s: jnp.ndarray
    load_time_s: jnp.ndarray
    kind: tuple[str, ...] = eqx.field(static=True)
    plant_scale: dict = eqx.field(default_factory=dict)
    initial_speed_m: jnp.ndarray | None = None
    initial_theta_e: jnp.ndarray | None = None
    observe_from_s: jnp.ndarray | None = None
    angle_modulo: float = eqx.field(static=True, default=2.0 * np.pi)

    @property
    def size(self) -> int:
        """Number of scenarios ``B`` in the batch."""
        return len(self.kind)

    @property
    def horizon_s(self) -> float:
        """Simulated time shared by every scenario, s; each one's own `duration_s` ends earlier or there
        ([`active`][tuning.autotune.scenario_batches.ScenarioBatch.active] masks the samples after it)."""
        return self.scenarios.duration_s

    def active(self, t: jnp.ndarray) -> jnp.ndarray:
        """``(B, N)`` 1.0 where sample time ``t (N,)`` lies inside each scenario's duration, else 0.0."""
        return (t[None, :] < self.duration_s[:, None] - 1e-12).astype(t.dtype)


def make_batch(
    n: int,
    seed: int,
    *,
    speed_rpm: tuple[float, float] = (200.0, 1500.0),
    load_nm: tuple[float, float] = (0.0, 10.0),
    duration_s: tuple[float, float] = (0.3, 0.5),
    kinds: Sequence[str] = ("step",),
    plant_spread: dict | None = None,
    Ts: float = BOOK_TS,
) -> ScenarioBatch:
    """``n`` scenarios drawn reproducibly from ``seed``.

    Each scenario starts at rest; the speed reference goes to ``+-U(speed_rpm)`` (both directions) as a
    step, a ramp (over 20-40 % of the pre-load window) or a reversal (step, then the opposite speed at
    40 % of the duration); a load torque of ``U(load_nm)`` opposing the motion steps in at 55-70 % of the
    duration. Durations are drawn from ``duration_s`` and rounded to whole periods ``Ts``.

    ``plant_spread = {"J": 0.5, "R": 0.2, ...}`` draws each scenario's plant parameter uniformly within
    +-50 %, +-20 %, ... of nominal (``current_offset_a``: an absolute half-width in A, every sensor drawn
    independently; see
    [`ScenarioBatch.plant_scale`][tuning.autotune.scenario_batches.ScenarioBatch]; ``u_dc_v`` scales the DC
    link, ``L_ls`` a multi-phase motor's leakage inductance); a ``(low, high)`` pair instead of a half-width
    draws the factor uniformly in ``[low, high]`` (a drive file's ``[operating]`` bands:
    [`tuning.autotune.drive_scaling.plant_spread`][tuning.autotune.drive_scaling.plant_spread]).
    """
    if n < 1:
        raise ParameterError(f"a scenario batch needs n >= 1 scenarios, got {n}.")
    bad = [k for k in kinds if k not in KINDS]
    if bad or not kinds:
        raise ParameterError(f"kinds must be a non-empty subset of {KINDS}, got {list(kinds)}.")
    for name, (lo, hi) in (("speed_rpm", speed_rpm), ("load_nm", load_nm), ("duration_s", duration_s)):
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 <= lo <= hi):
            raise ParameterError(f"{name} range must be finite with 0 <= low <= high, got ({lo}, {hi}).")
    if duration_s[0] <= 0:
        raise ParameterError(f"duration_s must be positive, got {duration_s}.")
    spread = dict(plant_spread or {})
    allowed = ("R", "L_d", "L_q", "psi_f", "J", "B", "L_ls", "u_dc_v", "initial_k", "ambient_k")
    allowed += SENSOR_SPREADS
    allowed += ("load_inertia", "shaft_stiffness", "shaft_damping")  # a compliant shaft's
    for name, frac in spread.items():
        if name not in allowed:
            raise ParameterError(f"plant_spread: unknown motor parameter {name!r}; choose from {allowed}.")
        if name == "current_offset_a":
            if not (np.isfinite(frac) and frac >= 0):
                raise ParameterError(
                    f"plant_spread['current_offset_a'] = {frac} must be a half-width >= 0, A."
                )
        elif isinstance(frac, (tuple, list)):
            if not (len(frac) == 2 and all(np.isfinite(frac)) and 0 < frac[0] <= frac[1]):
                raise ParameterError(
                    f"plant_spread[{name!r}] = {frac} must be factors (low, high) with 0 < low <= high."
                )
        elif not (np.isfinite(frac) and 0 <= frac < 1):
            raise ParameterError(
                f"plant_spread[{name!r}] = {frac} must be a fraction in [0, 1) (e.g. 0.2 for +-20 %)."
            )
    rng = np.random.default_rng(seed)
    horizon = round(duration_s[1] / Ts) * Ts
    rows, durations, load_times, kind_list = [], [], [], []
    for _ in range(n):
        kind = str(rng.choice(list(kinds)))
        direction = rng.choice([-1.0, 1.0])
        speed = direction * rpm_to_rad_s(rng.uniform(*speed_rpm))
        load = direction * rng.uniform(*load_nm)
        duration = round(rng.uniform(*duration_s) / Ts) * Ts
        t_load = round(rng.uniform(0.55, 0.70) * duration / Ts) * Ts
        if kind == "step":
            speed_ref = Profile.constant(speed)
        elif kind == "ramp":
            t_ramp = round(rng.uniform(0.2, 0.4) * t_load / Ts) * Ts
            speed_ref = Profile.ramp(0.0, t_ramp, 0.0, speed)
        else:
            t_rev = round(0.4 * duration / Ts) * Ts
            speed_ref = Profile.step(t_rev, speed, -speed)
            load = -load  # the load still opposes the motion after the reversal
        rows.append(Scenario(horizon, speed_ref=speed_ref, load_torque=Profile.step(t_load, 0.0, load)))
        durations.append(duration)
        load_times.append(t_load)
        kind_list.append(kind)
    # Drawn after the scenarios, so adding a spread leaves the scenarios of a seed unchanged.
    scale = plant_factors(rng, spread, n)
    return ScenarioBatch(
        stack_scenarios(rows), jnp.asarray(durations), jnp.asarray(load_times), tuple(kind_list), scale
    )


#: The spreads that draw the current sensors, one value per sensor.
SENSOR_SPREADS = ("current_offset_a", "current_gain")


def plant_factors(rng, spread: dict, n: int) -> dict:
    """``{name: (n,) factor}`` drawn from ``rng``: ``1 + U(-f, f)`` for a half-width ``f``, ``U(low, high)``
    for a ``(low, high)`` pair (``make_batch``'s ``plant_spread``)."""
    out = {}
    for name, frac in spread.items():
        if name in SENSOR_SPREADS:  # one draw per sensor (three columns; k sensors use the first k)
            centre = 0.0 if name == "current_offset_a" else 1.0
            out[name] = jnp.asarray(centre + rng.uniform(-frac, frac, (n, 3)))
        elif isinstance(frac, (tuple, list)):
            out[name] = jnp.asarray(rng.uniform(frac[0], frac[1], n))
        else:
            out[name] = jnp.asarray(1.0 + rng.uniform(-frac, frac, n))
    return out
