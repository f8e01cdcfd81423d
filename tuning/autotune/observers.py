"""What ``pmsmjax tune --estimator NAME`` tunes for each chapter 5 observer, on which drive and scenarios.

Per observer ([`pmsmjax.estimators.OBSERVERS`][pmsmjax.estimators.catalogue.OBSERVERS]), the parameters tuned
by default, as dotted paths of the drive (the observer sits at ``estimator.observer``, both in the tuning
drive's [`SensoredWarmup`][pmsmjax.estimators.sensored_warmup.SensoredWarmup] and in the I/f start's
[`StartupEstimator`][pmsmjax.estimators.startup.StartupEstimator], so a tuned gains.toml applies to either).
Every parameter is positive and tuned as ``log(p / p0)`` from the design rule
([`tuning.parameters`][tuning.parameters]):

=============  ==================================================================================
smo            ``k`` (V), ``width`` (A), ``omega_c`` (rad/s), ``speed_bandwidth`` (rad/s)
smo-pll        ``k``, ``width``, ``omega_c``, ``pll.kp`` (1/s), ``pll.ki`` (1/s^2)
adaptive-smo   ``k``, ``width``, ``l`` (rad/s), ``gamma`` (1/s^2)
dq-smo         ``k``, ``width``, ``omega_c``, ``pll.kp``, ``pll.ki``
mras           ``kp`` ((rad/s)/A^2), ``ki`` ((rad/s^2)/A^2)
ekf            ``q[0..3]`` (A^2, A^2, (rad/s)^2, rad^2), ``r[0..1]`` (A^2): the diagonals of Q and R
=============  ==================================================================================

(``P0`` is not tuned: the filter converges during the sensored warm-up, so it hardly enters the cost.)

On a drive file with a flux map the tuned observer is the map-aware one the I/f-start drives run
([`pmsmjax.assemble.map_aware`][pmsmjax.assemble.map_aware]): ``flux-observer`` reads the map itself and
keeps its paths; a back-EMF observer or the EKF sits inside the map's angle correction
([`MapAngleCorrected`][pmsmjax.estimators.map_angle_corrected.MapAngleCorrected]), one level down, so its
gains are ``estimator.observer.observer.<gain>``
([`tuned_names`][tuning.autotune.observers.tuned_names]), the same paths as in ``demo --motor FILE
--estimator NAME`` (the correction under the I/f start). The gradient then runs through the map's bicubic
interpolant (the correction angle at the operating current; the flux observer's current-flux relation).

Smooth surrogate: the SMOs' switching function is the sigmoid, which is their default as well (the
``sign`` function chatters at 10 kHz and has no useful derivative), so the tuned
and the evaluated observer are the same and ``surrogate`` is empty (a ``{"switching": ...}`` there would
tune on that law and re-evaluate on the default, as the controls' table does). The loss is made smooth
by the scenarios instead: each starts at speed with the drive on its sensor for ``WARMUP_S`` while the
observer converges, then on the observer
([`pmsmjax.estimators.sensored_warmup`][pmsmjax.estimators.sensored_warmup]: the hand-over is at a fixed time,
so no comparator depends on a gain). An I/f start from standstill was not used: whether a back-EMF observer
locks after it depends on the scenario (smo-pll and adaptive-smo lose the angle after an I/f start followed by
100 r/min or by a reversal), and a lost lock is a jump in the loss, not a slope.

Objective: the tune machinery's batch cost ([`tuning.autotune.objectives`][tuning.autotune.objectives]) with
``itae`` (speed ITAE of the sensorless drive, rad s) plus ``angle_error`` times the RMS of the wrapped
electrical angle error after the hand-over (rad, as the RMS chord ``2 sin(e/2)``: smooth through +-pi),
averaged over the batch; the voltage-saturation penalty stays. The overshoot penalty is off (each scenario
starts at a speed, the pre-load window holds steps both ways, and observer gains hardly move the speed loop's
overshoot; the ITAE prices the speed response), and so is the current penalty: the peak phase current exceeds
the limit only where the angle is lost (27 A against 15 in a reversal), which the angle term prices already,
and as a maximum over time it put kinks into the loss that stalled BFGS (measured on smo: 80 % of the cost,
no accepted step in 42 iterations).
``ANGLE_WEIGHT`` (rad s per rad) makes 1 electrical degree RMS cost as much as 0.17 rad s of ITAE, about
a batch scenario's whole ITAE: most of the ITAE is the speed loop's own step response, which the
observer's gains hardly move, so with a weight 5x lower the angle term would be 7 % of the
EKF's cost and the tuner would stop on the relative-improvement rule before the angle error moved.

Measurement noise (``NOISE_CURRENT_A``, ``NOISE_VOLTAGE_V``) is added to what the observer samples: a
noise-free closed loop rewards high observer gains without limit (tuned noise-free, the smo's linear-zone
pole went to -0.97 and its gains gave 20 electrical degrees RMS on the 0.5 % noise logs of
benchmarks/observer_accuracy.py at 300-600 r/min, against the design rule's 0.5).
"""

import dataclasses

import jax.numpy as jnp
import numpy as np

from pmsmjax import Profile, Scenario, presets, stack_scenarios
from pmsmjax.assemble import spec_drive, spec_motor, with_map_aware_estimator
from pmsmjax.estimators.registry import check_observer_name
from pmsmjax.estimators.sensored_warmup import SensoredWarmup
from pmsmjax.io.drive_files import drive_spec
from pmsmjax.presets.book_constants import BOOK_TS
from pmsmjax.spec.drive_spec import DriveSpec
from pmsmjax.spec.validation import ParameterError
from pmsmjax.units import rpm_to_rad_s
from tuning.autotune.drive_scaling import noise_scale
from tuning.autotune.hfi_tuning import injection_sensorless_drive
from tuning.autotune.scenario_batches import WARMUP_S, ScenarioBatch, plant_factors
from tuning.parameters import get_leaf, set_leaves

#: Rated speed of the book drive for the observer batches, r/min (the top of the observer accuracy bands;
#: the book motor reaches it under the 10 N m load with the 560 V link); 5 % of it is 100 r/min.
RATED_SPEED_RPM = 2000.0
#: Time the reference holds the start speed after the warm-up, and the load step at least after the speed
#: step, s (book drive; scaled with the drive's tuning durations,
#: [`tuning.autotune.drive_scaling`][tuning.autotune.drive_scaling]).
HOLD_S = 0.02
#: Measurement noise on the observer's samples while tuning, per axis: 0.05 A (0.5 % of the book drive's
#: 10 A, the EKF design rule's current noise) and 0.25 V (0.5 % of the 50 V phase voltage at about
#: 600 r/min; the 0.5 % logs of benchmarks/observer_accuracy.py have 0.17-0.85 V from 400 to 2000 r/min).
#: With it the design-rule smo keeps 0.3-0.5 degrees RMS at 300 r/min and above, as on those logs.
#: Noise-free tuning rewarded gains that fail with noise
#: ([`pmsmjax.estimators.sensored_warmup`][pmsmjax.estimators.sensored_warmup]).
NOISE_CURRENT_A = 0.05
NOISE_VOLTAGE_V = 0.25
#: Objective weight of the RMS angle error, (rad s) per electrical rad: 1 degree RMS ~ 0.17 rad s of ITAE.
ANGLE_WEIGHT = 10.0
#: Optimiser settings of ``pmsmjax tune --estimator`` when no config is given: Adam, not the controls' BFGS.
#: The observer losses are rough at the scale of BFGS's trial steps (scenarios near a lost lock at low speed
#: and full load): BFGS stalled (smo, 32 scenarios: best cost 1.18 from 1.43, where Nelder-Mead reached
#: 0.86). Adam's step 0.2: with 0.1 (and 0.05) it stopped on the smo at 1.08 (1.18); with 0.2 it reached
#: 0.853 and the ekf 0.1959 (0.1988 with 0.1) (benchmarks/bench_observer_tuning.py problem). Bounds
#: 0.01-100: the EKF's covariances span decades.
OBSERVER_CONFIG = dict(
    method="adam", learning_rate=0.2, max_iterations=120, patience=40, bounds=(0.01, 100.0)
)
#: Scenario kinds of the observer batches.
OBSERVER_KINDS = ("step", "reversal")

_SMO = ("k", "width")


def _paths(*names: str) -> tuple[str, ...]:
    return tuple(f"estimator.observer.{n}" for n in names)


@dataclasses.dataclass(frozen=True)
class ObserverTuning:
    """`names`: the parameters tuned by default (dotted paths of the drive); `surrogate`: design-rule
    options of the differentiated observer (the smooth switching); `weights`: ObjectiveWeights fields."""

    names: tuple[str, ...]
    surrogate: dict = dataclasses.field(default_factory=dict)
    weights: dict = dataclasses.field(
        default_factory=lambda: dict(itae=1.0, angle_error=ANGLE_WEIGHT, overshoot=0.0, current_penalty=0.0)
    )
    #: chapter 6 (HF injection, hybrid): the salient, saturated drive and the low-speed batches
    chapter6: bool = False


TUNABLE_OBSERVERS = {
    "smo": ObserverTuning(_paths(*_SMO, "omega_c", "speed_bandwidth")),
    "smo-pll": ObserverTuning(_paths(*_SMO, "omega_c", "pll.kp", "pll.ki")),
    "adaptive-smo": ObserverTuning(_paths(*_SMO, "l", "gamma")),
    "dq-smo": ObserverTuning(_paths(*_SMO, "omega_c", "pll.kp", "pll.ki")),
    "mras": ObserverTuning(_paths("kp", "ki")),
    "ekf": ObserverTuning(_paths(*(f"q[{i}]" for i in range(4)), "r[0]", "r[1]")),
    "flux-observer": ObserverTuning(_paths("sigma0", "zeta", "k_theta", "k_omega")),
    # chapter 6: filter cut-offs and PLL gains (rad/s, 1/s, 1/s^2); tuning.autotune.hfi_tuning
    "hfi-rotating": ObserverTuning(
        _paths("bandpass_bandwidth", "sequence_cutoff", "error_cutoff", "pll.kp", "pll.ki"), chapter6=True
    ),
    "hfi-pulsating": ObserverTuning(
        _paths("bandpass_bandwidth", "error_cutoff", "pll.kp", "pll.ki"), chapter6=True
    ),
    "hybrid": ObserverTuning(
        _paths(
            "injection.bandpass_bandwidth",
            "injection.sequence_cutoff",
            "injection.error_cutoff",
            "injection.pll.kp",
            "injection.pll.ki",
            "low_speed",
            "high_speed",
            "injection_off_speed",
        ),
        chapter6=True,
    ),
}


def observer_tuning(name: str) -> ObserverTuning:
    """The default tuning job of observer `name`; [`ParameterError`][pmsmjax.spec.validation.ParameterError]
    listing the tunable observers for another name."""
    check_observer_name(name)
    if name not in TUNABLE_OBSERVERS:
        raise ParameterError(
            f"pmsmjax tune tunes the observers {', '.join(TUNABLE_OBSERVERS)}, not {name!r}."
        )
    return TUNABLE_OBSERVERS[name]


def tuned_names(name: str, drive) -> tuple[str, ...]:
    """The default tuned parameters of observer ``name`` (``observer_tuning(name).names``) as paths of
    ``drive`` (an [`observer_drive`][tuning.autotune.observers.observer_drive]): one level further down
    wherever the path passes a map-aware wrapper, ``estimator.observer.observer.<gain>`` for an observer
    inside [`AbstractMapAwareObserver`][pmsmjax.estimators.map_scheduled.AbstractMapAwareObserver] (the flux
    map's angle correction), ``estimator.observer.injection.<gain>`` for HF injection inside
    [`CrossSaturationCompensated`][pmsmjax.estimators.hfi_cross_saturation.CrossSaturationCompensated]
    (and ``estimator.observer.injection.injection.<gain>`` for the hybrid's)."""
    return tuple(_through_wrappers(drive, n) for n in observer_tuning(name).names)


def _through_wrappers(drive, path: str) -> str:
    from pmsmjax.estimators.hfi_cross_saturation import CrossSaturationCompensated
    from pmsmjax.estimators.map_scheduled import AbstractMapAwareObserver

    inner = {AbstractMapAwareObserver: "observer", CrossSaturationCompensated: "injection"}
    out, node = [], drive
    for part in path.split("."):
        wrapped = next((field for kind, field in inner.items() if isinstance(node, kind)), None)
        if wrapped is not None and part != wrapped:  # a gain of the wrapped estimator, not of the wrapper
            out.append(wrapped)
            node = getattr(node, wrapped)
        out.append(part)
        node = getattr(node, part.split("[")[0], None)
    return ".".join(out)


def observer_drive(
    name: str,
    *,
    spec: DriveSpec | None = None,
    n_substeps: int = 10,
    warmup_s: float = WARMUP_S,
    noise: bool = True,
    observer_options=None,
    observer_model: str = "map",
    **kw,
):
    """The FOC drive of the drive file ``spec`` (default the book drive;
    [`pmsmjax.assemble.spec_drive`][pmsmjax.assemble.spec_drive]) on observer ``name`` (design-rule gains for
    the drive's motor, overridden by ``observer_options``) behind a sensored warm-up of ``warmup_s`` (s), with
    the measurement noise ``NOISE_CURRENT_A``, ``NOISE_VOLTAGE_V`` (scaled to the drive's current limit
    and DC link, [`tuning.autotune.drive_scaling.noise_scale`][tuning.autotune.drive_scaling.noise_scale]) on
    the observer's samples unless ``noise=False``; ``kw`` are preset options of the FOC drive (``n_substeps``,
    ...). On a file with a flux map a chapter 5 observer reads the map (``observer_model="map"``,
    [`pmsmjax.assemble.with_map_aware_estimator`][pmsmjax.assemble.with_map_aware_estimator]; its gains'
    paths: [`tuned_names`][tuning.autotune.observers.tuned_names]) or keeps the file's constant ``L_d``,
    ``L_q``, ``psi_f`` (``"constant"``)."""
    spec = drive_spec("book") if spec is None else spec
    if observer_model not in ("map", "constant"):
        raise ParameterError(f"observer_model must be 'map' or 'constant', got {observer_model!r}.")
    if observer_tuning(name).chapter6:
        drive = injection_sensorless_drive(name, observer_options, spec, n_substeps=n_substeps, **kw)
    else:
        foc = spec_drive(spec, "pi", n_substeps=n_substeps, **kw)
        drive = presets.with_observer(foc, name, spec_motor(spec), observer_options, startup=False)
        if spec.flux_map is not None and observer_model == "map":
            drive = with_map_aware_estimator(spec, drive)
    i_scale, u_scale = noise_scale(spec)
    levels = (NOISE_CURRENT_A * i_scale, NOISE_VOLTAGE_V * u_scale) if noise else (0.0, 0.0)
    drive = set_leaves(drive, ["estimator"], [SensoredWarmup(drive.estimator, warmup_s, *levels)])
    # A gain stored as a Python float (the SMO's speed_bandwidth) is not an array leaf: make the tunable
    # ones arrays so they can be named, differentiated and vmapped.
    dtype = drive.machine.motor.R.dtype
    names = [n for n in tuned_names(name, drive) if not isinstance(get_leaf(drive, n), jnp.ndarray)]
    return set_leaves(drive, names, [jnp.asarray(get_leaf(drive, n), dtype) for n in names])


def make_observer_batch(
    n: int,
    seed: int,
    *,
    speed_rpm: tuple[float, float] = (0.05 * RATED_SPEED_RPM, RATED_SPEED_RPM),
    start_rpm: tuple[float, float] = (0.25 * RATED_SPEED_RPM, RATED_SPEED_RPM),
    load_nm: tuple[float, float] = (0.0, 10.0),
    duration_s: tuple[float, float] = (0.15, 0.25),
    kinds=OBSERVER_KINDS,
    plant_spread: dict | None = None,
    warmup_s: float = WARMUP_S,
    hold_s: float = HOLD_S,
    Ts: float = BOOK_TS,
) -> ScenarioBatch:
    """``n`` observer scenarios drawn reproducibly from ``seed``.

    Each starts at a speed ``w0`` drawn log-uniformly from ``start_rpm`` (25-100 % of rated: a cold EKF or
    MRAS does not converge within the 20 ms warm-up at 100-200 r/min, measured 20-97 degrees RMS after
    it), either direction, at a random angle; the reference holds ``w0`` through the warm-up and
    ``hold_s`` (20 ms) after it, then steps to ``w1`` (``"step"``: same direction, drawn log-uniformly
    from ``speed_rpm``, down to 5 % of rated, so low speeds are as common as high ones; ``"reversal"``:
    ``-w0``); a load of
    ``U(load_nm)`` opposing the final motion steps in at 55-70 % of the duration. ``plant_spread`` as in
    [`tuning.autotune.scenario_batches.make_batch`][tuning.autotune.scenario_batches.make_batch] (the
    observer's motor model stays nominal: a model mismatch).
    """
    if n < 1:
        raise ParameterError(f"a scenario batch needs n >= 1 scenarios, got {n}.")
    bad = [k for k in kinds if k not in OBSERVER_KINDS]
    if bad or not kinds:
        raise ParameterError(f"kinds must be a non-empty subset of {OBSERVER_KINDS}, got {list(kinds)}.")
    for label, (lo, hi) in (("speed_rpm", speed_rpm), ("start_rpm", start_rpm)):
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo <= hi):
            raise ParameterError(f"{label} range must be finite with 0 < low <= high, got ({lo}, {hi}).")
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
    draw = lambda r: rpm_to_rad_s(np.exp(rng.uniform(np.log(r[0]), np.log(r[1]))))
    horizon = round(duration_s[1] / Ts) * Ts
    rows, durations, load_times, kind_list, w0s, th0s = [], [], [], [], [], []
    for _ in range(n):
        kind = str(rng.choice(list(kinds)))
        direction = rng.choice([-1.0, 1.0])
        w0 = direction * draw(start_rpm)
        w1 = direction * draw(speed_rpm) if kind == "step" else -w0
        duration = round(rng.uniform(*duration_s) / Ts) * Ts
        t_load = round(rng.uniform(0.55, 0.70) * duration / Ts) * Ts
        load = np.sign(w1) * rng.uniform(*load_nm)
        rows.append(
            Scenario(
                horizon, speed_ref=Profile.step(t_step, w0, w1), load_torque=Profile.step(t_load, 0.0, load)
            )
        )
        durations.append(duration)
        load_times.append(t_load)
        kind_list.append(kind)
        w0s.append(w0)
        th0s.append(rng.uniform(-np.pi, np.pi))
    spread = dict(plant_spread or {})
    scale = plant_factors(rng, spread, n)
    return ScenarioBatch(
        stack_scenarios(rows),
        jnp.asarray(durations),
        jnp.asarray(load_times),
        tuple(kind_list),
        scale,
        initial_speed_m=jnp.asarray(w0s),
        initial_theta_e=jnp.asarray(th0s),
        observe_from_s=jnp.full((n,), warmup_s),
    )
