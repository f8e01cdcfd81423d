"""The chapter 6 estimators in ``pmsmjax tune --estimator``: their drive and their
low-speed scenario batches. The tuner, objective, outputs and resume are those of the chapter 5 observers
([`tuning.autotune.observers`][tuning.autotune.observers], whose ``TUNABLE_OBSERVERS`` lists what is tuned).

Drive ([`injection_sensorless_drive`][tuning.autotune.hfi_tuning.injection_sensorless_drive]): the FOC drive
of the drive file (for the book drive the salient book motor, ``L_d`` 5.25 mH, ``L_q`` 12 mH; any other drive
file must be salient) with the estimator's design rule, on the plant with d-axis saturation
([`pmsmjax.machines.saturated_machine`][pmsmjax.machines.saturation.saturated_machine], defaults on the book
drive), as
[`pmsmjax.jobs.estimator_comparison.chapter6_drive`][pmsmjax.jobs.estimator_comparison.chapter6_drive] builds
it for ``compare --estimator``;
[`tuning.autotune.observers.observer_drive`][tuning.autotune.observers.observer_drive] puts it behind the same
sensored warm-up and measurement noise as the chapter 5 observers.

Polarity. The injection estimators find the d axis modulo pi: the estimator starts at ``theta0 = 0`` and
locks to the pole within +-90 degrees of it. The batches therefore start the rotor within
``INITIAL_ANGLE_DEG`` of 0 (polarity known, as after the start-up detection of
[`pmsmjax.estimators.polarity`][pmsmjax.estimators.polarity]), and the angle error is scored modulo pi
(``ScenarioBatch.angle_modulo``); a lock on the wrong pole would turn the torque around and show in the
ITAE. The hybrid is tuned without its polarity detector (``polarity=False``): its current pulses at
the start would run during the sensored warm-up, and the polarity is known here. Its tuned names are
therefore ``estimator.observer.injection.*`` (with the detector the injection sits one level deeper,
``injection.observer.*``).

Scenarios ([`make_injection_batch`][tuning.autotune.hfi_tuning.make_injection_batch]), chosen for the methods'
range, standstill and low speed:

- ``"standstill"``: the reference is 0 throughout; a load step of 2-10 N m (either sign) at 55-70 % of
  the scenario;
- ``"slow"``: start at a speed drawn uniformly within +-``max_rpm`` (100 r/min for the injection
  estimators: slow speed changes within +-100 r/min), the reference steps 20 ms after the warm-up to
  another such speed (so reversals through zero are among them), and a 0-10 N m load (opposing the final
  motion) steps in at 55-70 %. For the hybrid ``max_rpm`` is 300 r/min, so that the scenarios cross its
  crossover band (50-150 r/min, carrier off at 250 r/min) whose edges are tuned.

These are the book drive's numbers; on another drive file each is the same share of its rated speed,
rated torque, current limit and tuning durations
([`tuning.autotune.drive_scaling`][tuning.autotune.drive_scaling]).
"""

import jax.numpy as jnp
import numpy as np

from pmsmjax import Profile, Scenario, presets, stack_scenarios
from pmsmjax.assemble import spec_drive, spec_motor
from pmsmjax.io.drive_files import drive_spec
from pmsmjax.machines.saturation import saturated_machine
from pmsmjax.presets.book_constants import BOOK_TS
from pmsmjax.spec.drive_spec import DriveSpec
from pmsmjax.spec.validation import ParameterError, plain
from pmsmjax.units import rpm_to_rad_s
from tuning.autotune.drive_scaling import noise_scale, speed_scale, torque_scale
from tuning.autotune.scenario_batches import WARMUP_S, ScenarioBatch, plant_factors
from tuning.parameters import set_leaves

#: Scenario kinds of the injection batches.
INJECTION_KINDS = ("standstill", "slow")
#: Largest initial rotor angle off the estimators' initial estimate, electrical degrees (polarity known).
INITIAL_ANGLE_DEG = 60.0
#: Speed range of the "slow" scenarios, r/min, per estimator (module docstring).
MAX_RPM = {"hfi-rotating": 100.0, "hfi-pulsating": 100.0, "hybrid": 300.0}
#: Smallest standstill load step, N m (book drive), and the hold after the warm-up, s.
STANDSTILL_LOAD_NM = 2.0
HOLD_S = 0.02
#: Current scale of the plant's d-axis saturation on the book drive, A
#: ([`pmsmjax.machines.saturated_machine`][pmsmjax.machines.saturation.saturated_machine]'s default).
SATURATION_CURRENT_A = 8.0
#: Least relative saturation L_q / L_d - 1 a drive needs for the injection estimators.
MIN_SALIENCY = 0.05


def injection_spec(spec: DriveSpec | None) -> DriveSpec:
    """The drive file the chapter 6 estimators run on: the salient book motor for the book drive (or
    none), else ``spec`` itself, which must be salient (L_q > L_d: the injection finds the d axis from
    the saliency). On a flux map the saliency is the map's at light load, not the linear model's at the
    rated current (whose q path may be saturated below L_d): the file is refused only where the map has no
    injection region at all
    ([`spec_injection_region`][pmsmjax.estimators.injection_region.spec_injection_region])."""
    if spec is None or spec.source == "book":
        return drive_spec("book_salient")
    if spec.flux_map is not None:
        from pmsmjax.estimators.injection_region import spec_injection_region

        spec_injection_region(spec)
        return spec
    L_d, L_q = spec.motor["L_d"], spec.motor["L_q"]
    if not L_q > L_d * (1.0 + MIN_SALIENCY):
        raise ParameterError(
            f"--motor {spec.source}: L_q = {plain(L_q)} H is not above L_d = {plain(L_d)} H by "
            f"{100 * MIN_SALIENCY:g} %; HF injection needs a salient machine: give --motor book_salient "
            "or a drive file of an interior-magnet motor, or tune a back-EMF observer (--estimator smo, ...)."
        )
    return spec


def injection_sensorless_drive(
    name: str, observer_options: dict | None = None, spec: DriveSpec | None = None, **kw
):
    """The FOC drive of [`injection_spec`][tuning.autotune.hfi_tuning.injection_spec] (the salient book motor
    by default) with the chapter 6 estimator ``name`` (design rule, overridden by ``observer_options``; the
    hybrid without its polarity detector), on the saturated plant (its current scale the book's 8 A times the
    drive's current limit over the book's 15 A); ``kw`` are preset options of the FOC drive (``n_substeps``,
    ...).

    On a drive file with a flux map the plant is the map's (as every command runs the file), the injection
    is designed on the map's incremental inductances at no load
    ([`map_injection_design`][pmsmjax.assemble.map_injection_design]) and runs map-aware
    ([`pmsmjax.assemble.map_aware`][pmsmjax.assemble.map_aware]: the cross-saturation angle taken out)."""
    spec = injection_spec(spec)
    motor = spec_motor(spec)
    options = dict(observer_options or {})
    if name == "hybrid":
        options = {"polarity": False, **options}
    foc = spec_drive(spec, "pi", **kw)
    if spec.flux_map is not None:
        from pmsmjax.assemble import map_injection_design, with_map_aware_estimator

        model, options = map_injection_design(spec, name, motor, options)
        drive = presets.with_observer(foc, name, model, options, startup=False)
        return with_map_aware_estimator(spec, drive)
    drive = presets.with_observer(foc, name, motor, options, startup=False)
    current_scale = SATURATION_CURRENT_A * noise_scale(spec)[0]
    return set_leaves(drive, ["machine"], [saturated_machine(motor, current_scale=current_scale)])


def make_injection_batch(
    n: int,
    seed: int,
    *,
    max_rpm: float = 100.0,
    load_nm: tuple[float, float] = (0.0, 10.0),
    duration_s: tuple[float, float] = (0.15, 0.25),
    kinds=INJECTION_KINDS,
    plant_spread: dict | None = None,
    warmup_s: float = WARMUP_S,
    hold_s: float = HOLD_S,
    standstill_load_nm: float = STANDSTILL_LOAD_NM,
    Ts: float = BOOK_TS,
) -> ScenarioBatch:
    """``n`` low-speed scenarios drawn reproducibly from ``seed`` (module docstring), scored modulo pi;
    the standstill load steps are at least ``standstill_load_nm``, the speed steps ``hold_s`` after the
    warm-up. ``plant_spread`` as in
    [`tuning.autotune.scenario_batches.make_batch`][tuning.autotune.scenario_batches.make_batch]."""
    if n < 1:
        raise ParameterError(f"a scenario batch needs n >= 1 scenarios, got {n}.")
    bad = [k for k in kinds if k not in INJECTION_KINDS]
    if bad or not kinds:
        raise ParameterError(f"kinds must be a non-empty subset of {INJECTION_KINDS}, got {list(kinds)}.")
    if not (np.isfinite(max_rpm) and max_rpm > 0):
        raise ParameterError(f"max_rpm must be a positive speed in r/min, got {max_rpm}.")
    if not 0 < duration_s[0] <= duration_s[1]:
        raise ParameterError(f"duration_s must be positive with low <= high, got {duration_s}.")
    t_step = round((warmup_s + hold_s) / Ts) * Ts
    if duration_s[0] * 0.55 <= t_step + hold_s:
        raise ParameterError(
            f"duration_s {duration_s} too short: the load step (at 55 % of it) must come "
            f"{hold_s * 1e3:.3g} ms after the speed step at {t_step:.3f} s; make the shortest duration at "
            f"least {(t_step + hold_s) / 0.55:.3f} s."
        )
    rng = np.random.default_rng(seed)
    w_max = rpm_to_rad_s(max_rpm)
    horizon = round(duration_s[1] / Ts) * Ts
    rows, durations, load_times, kind_list, w0s, th0s = [], [], [], [], [], []
    for _ in range(n):
        kind = str(rng.choice(list(kinds)))
        if kind == "standstill":
            w0 = w1 = 0.0
            load = rng.choice([-1.0, 1.0]) * rng.uniform(
                max(load_nm[0], standstill_load_nm), max(load_nm[1], standstill_load_nm)
            )
        else:
            w0, w1 = rng.uniform(-w_max, w_max, 2)
            sign = np.sign(w1) if w1 != 0 else 1.0
            load = sign * rng.uniform(*load_nm)
        duration = round(rng.uniform(*duration_s) / Ts) * Ts
        t_load = round(rng.uniform(0.55, 0.70) * duration / Ts) * Ts
        rows.append(
            Scenario(
                horizon,
                speed_ref=Profile.step(t_step, float(w0), float(w1)),
                load_torque=Profile.step(t_load, 0.0, float(load)),
            )
        )
        durations.append(duration)
        load_times.append(t_load)
        kind_list.append(kind)
        w0s.append(float(w0))
        th0s.append(np.radians(rng.uniform(-INITIAL_ANGLE_DEG, INITIAL_ANGLE_DEG)))
    scale = plant_factors(rng, dict(plant_spread or {}), n)
    return ScenarioBatch(
        stack_scenarios(rows),
        jnp.asarray(durations),
        jnp.asarray(load_times),
        tuple(kind_list),
        scale,
        initial_speed_m=jnp.asarray(w0s),
        initial_theta_e=jnp.asarray(th0s),
        observe_from_s=jnp.full((n,), warmup_s),
        angle_modulo=float(np.pi),
    )


def injection_load_nm(name: str, spec: DriveSpec | None = None) -> tuple[float, float]:
    """The load range of ``name``'s tuning batches, N m: up to the drive's rated torque
    ([`injection_spec`][tuning.autotune.hfi_tuning.injection_spec]); on a flux map the injection estimators'
    loads stop at the map's injection region
    ([`spec_injection_region`][pmsmjax.estimators.injection_region.spec_injection_region]), beyond which
    they lose the d axis whatever their gains (the hybrid's keep the rated torque: it hands over to its
    back-EMF observer there)."""
    spec = injection_spec(spec)
    top = spec.ratings["rated_torque_nm"]
    if spec.flux_map is not None and name != "hybrid":
        from pmsmjax.estimators.injection_region import spec_injection_region

        top = min(top, spec_injection_region(spec).max_torque_nm)
    return 0.0, top


def injection_batch_maker(name: str, spec: DriveSpec | None = None):
    """The batch maker of chapter 6 estimator ``name`` for the tune job:
    [`make_injection_batch`][tuning.autotune.hfi_tuning.make_injection_batch] at its
    [`MAX_RPM`][tuning.autotune.hfi_tuning.MAX_RPM] and
    [`STANDSTILL_LOAD_NM`][tuning.autotune.hfi_tuning.STANDSTILL_LOAD_NM] scaled to the drive
    ([`injection_spec`][tuning.autotune.hfi_tuning.injection_spec]'s rated speed and torque over the book's;
    the standstill load at most [`injection_load_nm`][tuning.autotune.hfi_tuning.injection_load_nm]'s top);
    the job's default kinds (the chapter 5 ``("step",)``) mean
    [`INJECTION_KINDS`][tuning.autotune.hfi_tuning.INJECTION_KINDS]."""
    spec = injection_spec(spec)
    max_rpm, standstill = MAX_RPM[name] * speed_scale(spec), STANDSTILL_LOAD_NM * torque_scale(spec)
    standstill = min(standstill, injection_load_nm(name, spec)[1])  # inside a map's injection region

    def make(n, seed, *, kinds=INJECTION_KINDS, **options):
        kinds = INJECTION_KINDS if tuple(kinds) == ("step",) else tuple(kinds)
        return make_injection_batch(
            n, seed, max_rpm=max_rpm, kinds=kinds, standstill_load_nm=standstill, **options
        )

    return make
