"""What a Monte Carlo study varies and how: the study settings, their TOML file, and applying a sample.

A study runs the scenario form of the book (speed step from rest to ``speed_rpm`` at t = 0, load step
0 -> ``load_nm`` at ``load_time_s``, ``duration_s`` long) on the user's drive: a drive file or preset
(``motor``, [`pmsmjax.io.drive_files.drive_spec`][pmsmjax.io.drive_files.drive_spec]) built by
[`pmsmjax.assemble.spec_drive`][pmsmjax.assemble.spec_drive] at the file's DC link, control rate, current
limit and bandwidths (optionally with tuned gains from ``pmsmjax tune``). What the study leaves out comes from
the drive file: the scenario (``[scenario]``), the current limit and with it the failure threshold
(``[ratings] max_current_a``), the DC link, the bandwidths, and the default tolerances (``[tolerances]``,
[`default_tolerances`][tuning.montecarlo.study.default_tolerances]); ``--motor book`` (the default) is the
book drive, bit for bit. Each varied parameter is named by a dotted path:

- ``motor.R``, ``motor.L_d``, ``motor.L_q``, ``motor.psi_f``, ``motor.J``, ``motor.B`` (six- and five-phase
  also ``motor.L_ls``): the *plant's* motor. The controller's own motor model (decoupling, delay
  compensation) stays nominal, as on a real drive whose firmware holds the data-sheet values.
- ``bridge.u_dc``: the DC-link voltage, V.
- ``current_sensor.offset_a[k]``, ``current_sensor.gain[k]``: sensor ``k``'s offset (A; its tolerance is
  an absolute half-width in A, since the nominal offset may be 0) and gain (relative), on a drive file
  whose ``[sensor]`` gives current sensors; the file's ``[tolerances] current_offset_a`` and
  ``current_gain`` spread every sensor independently.
- ``thermal.initial_k``, ``thermal.ambient_k``: a warm motor's (a drive file with ``[thermal]``) winding
  temperature at the start of the run and its ambient, K.
- ``controller.<path>``: any scalar array leaf of the controller, e.g. ``controller.speed.kp``.
- ``scenario.speed_rpm``, ``scenario.load_nm``: the speed step (r/min) and the load step (N m).

**Sensorless studies** (``estimator``): the drive runs on a chapter 5 observer
([`pmsmjax.estimators.OBSERVERS`][pmsmjax.estimators.catalogue.OBSERVERS]) with the drive file's I/f start
from standstill ([`pmsmjax.presets.with_observer`][pmsmjax.assemble.with_observer],
[`pmsmjax.assemble.startup_options`][pmsmjax.assemble.startup_options]). The observer's motor model, like the
controller's, is the *nominal* motor; the ``motor.*`` parameters perturb the *plant*, so every draw is a
plant/model mismatch as on a drive whose motor differs from its data sheet. The default set is then
[`SENSORLESS_TOLERANCES`][tuning.montecarlo.study.SENSORLESS_TOLERANCES] (R +-30 %, L_d and L_q +-20 % each,
drawn independently, psi_f +-10 %, uniform), whatever the drive file's ``[tolerances]``: they describe the
observer's model error, not the motor's spread. Independent L_d and L_q make the plant slightly salient (up to
about +-50 % L_q/L_d) where the nominal motor is not: part of the inductance error a non-salient observer
model sees.

The TOML file (every table and key optional; defaults below)::

    [study]        n, seed, sampling ("random" | "latin_hypercube"), chunk_size, nonphysical
                   ("refuse" | "clip"), decimate, sensitivity_runs
    [drive]        motor (preset or TOML file), gains (gains TOML from pmsmjax tune), current_bandwidth,
                   speed_bandwidth, current_limit, u_dc, n_substeps, unroll_substeps, estimator,
                   machine ("three-phase" | "six-phase" | "five-phase"), control and pwm
                   (pmsmjax.presets.six_phase, pmsmjax.presets.five_phase)
    [scenario]     speed_rpm, load_nm, load_time_s, duration_s
    [thresholds]   current_a, tracking_rpm
    [parameters."motor.R"]  distribution = "uniform", tolerance = 0.2, sigmas = 3.0, nominal = ...

A ``[parameters]`` table replaces the default set
([`default_tolerances`][tuning.montecarlo.study.default_tolerances]) as a whole; a parameter's nominal value
defaults to the drive's (or the scenario's) own. Drive and scenario values left out (None) are the drive
file's.

**Operating conditions** (``[operating]``, what varies in use, apart from the ``[tolerances]``, what is not
known): the default set adds each band as a uniform draw over it
([`operating_parameters`][tuning.montecarlo.study.operating_parameters]): the initial winding temperature
(``winding_temperature_c``) and the ambient (``ambient_c``) in kelvin, the DC link (``u_dc_v``, replacing
the ``u_dc_v`` tolerance).
"""

import dataclasses
import math

import jax.numpy as jnp

from pmsmjax import presets
from pmsmjax.drive import Drive
from pmsmjax.inverters.averaged import AveragedBridge
from pmsmjax.io.drive_files import drive_spec
from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.spec.drive_spec import TABLES, DriveSpec
from pmsmjax.spec.validation import ParameterError
from pmsmjax.units import rpm_to_rad_s
from tuning.montecarlo.distributions import KINDS, SAMPLING, Distribution
from tuning.montecarlo.physical_range import ABSOLUTE_PARAMETERS
from tuning.parameters import (
    apply_gains,
    array_leaf_names,
    check_gains,
    get_leaf,
    read_gains_toml,
    set_leaves,
)

#: The default tolerances of a drive file without ``[tolerances]`` (the book drive file states the same
#: set): manufacturing spread and temperature (R), inductance tolerance, magnet ageing and temperature
#: (psi_f), unknown load inertia (J), friction and DC-link sag, all uniform.
DEFAULT_TOLERANCES = {
    "motor.R": 0.20,
    "motor.L_d": 0.15,
    "motor.L_q": 0.15,
    "motor.psi_f": 0.10,
    "motor.J": 0.50,
    "motor.B": 0.50,
    "bridge.u_dc": 0.10,
}
#: The default set of a sensorless study: the plant/observer-model errors (module docstring), uniform.
SENSORLESS_TOLERANCES = {"motor.R": 0.30, "motor.L_d": 0.20, "motor.L_q": 0.20, "motor.psi_f": 0.10}
MOTOR_FIELDS = ("R", "L_d", "L_q", "psi_f", "J", "B")
SCENARIO_FIELDS = ("speed_rpm", "load_nm")
#: A drive file's ``[tolerances]`` key for a current sensor -> the drive leaf it spreads, one study parameter
#: per sensor (``current_sensor.offset_a[0]``, ...).
SENSOR_TOLERANCE_PARAMETERS = {
    "current_offset_a": "current_sensor.offset_a",
    "current_gain": "current_sensor.gain",
}
#: A drive file's ``[tolerances]`` key -> the study parameter it spreads (the current sensors': above).
TOLERANCE_PARAMETERS = {
    k: ("bridge.u_dc" if k == "u_dc_v" else f"motor.{k}")
    for k in TABLES["tolerances"]
    if k not in SENSOR_TOLERANCE_PARAMETERS
}
#: A compliant shaft's parameters ([`pmsmjax.machines.shaft`][pmsmjax.machines.shaft]) as study parameters.
SHAFT_FIELDS = ("load_inertia", "shaft_stiffness", "shaft_damping")
TOLERANCE_PARAMETERS["shaft_stiffness_nm_per_rad"] = "motor.shaft_stiffness"
#: The machine setting -> the drive file's phase count.
PHASES = {"three-phase": 3, "six-phase": 6, "five-phase": 5}
#: Periods between the fan chart's samples, at most (the largest divisor of the run's periods up to this).
DECIMATE_AT_MOST = 40
# Parameters that must stay > 0 (the rest of the drive's parameters must stay >= 0).


@dataclasses.dataclass(frozen=True)
class Study:
    """Settings of a Monte Carlo study (see the module docstring for the TOML layout).

    - `n`: number of runs; `seed`: sampling seed; `sampling`: ``random`` or ``latin_hypercube``.
    - `chunk_size`: most runs per chunk (one compiled call, one file on disk; chunks are balanced and
      rounded up to two runs per device), or ``"auto"`` (default): from the device's free memory and the
      drive's bytes per run, capped where throughput stops improving
      ([`tuning.montecarlo.chunking`][tuning.montecarlo.chunking]: 2048 on 2 CPU devices for runs of 256
      periods or more, the fastest of 256-8192 measured, more for shorter runs; 262,144 per GPU).
    - `nonphysical`: what to do with samples outside a parameter's physical range: ``refuse`` (error) or
      ``clip`` (moved to the bound, counted in the summary).
    - `decimate`: keep every this many periods of speed and current for the fan chart (None: the largest
      divisor of the run's periods up to 40).
    - `sensitivity_runs`: runs (the first ones) whose derivatives are taken by forward-mode AD.
    - `parameters`: ``{name: {"distribution", "tolerance", "sigmas", "nominal"}}`` (nominal optional).
    - drive: `motor` (preset name or drive file), `gains` (TOML path or None), `current_bandwidth` rad/s,
      `speed_bandwidth` rad/s, `current_limit` A, `u_dc` V (None: the drive file's), `n_substeps`,
      `unroll_substeps` (the RK4 sub-steps written out, not looped:
      [`pmsmjax.inverters.averaged.AveragedBridge`][pmsmjax.inverters.averaged.AveragedBridge]; for GPUs),
      `estimator` (a chapter 5 observer name, or None for the exact sensor; see the module docstring);
      scenario: `speed_rpm`, `load_nm`, `load_time_s`, `duration_s` (None: the drive file's ``[scenario]``).
    - thresholds: `current_threshold_a` (None: 1.05 times the current limit), `tracking_threshold_rpm`
      (mean speed error over the last 10 % of the run).
    - `machine`: ``three-phase``, ``six-phase``
      (`pmsmjax.presets.six_phase.six_phase_drive` on a six-phase
      drive file, ``book`` its rewind of the book motor) or ``five-phase``
      (`pmsmjax.presets.five_phase.five_phase_drive`);
      `control` and `pwm`: the scheme and modulator (None: ``vsd`` and ``four-vector`` / ``near-four-vector``;
      three phases take only the PI drive).
    - `linear_stability`: also linearise every draw at its final speed and load and flag a spectral radius
      >= 1 as the failure ``unstable_linearisation``
      ([`tuning.montecarlo.linear_stability`][tuning.montecarlo.linear_stability]).
    """

    n: int = 1000
    seed: int = 0
    sampling: str = "random"
    chunk_size: int | str = "auto"
    nonphysical: str = "refuse"
    decimate: int | None = None
    sensitivity_runs: int = 256
    parameters: dict | None = None  # None: DEFAULT_TOLERANCES, or SENSORLESS_TOLERANCES with an estimator
    motor: str = "book"
    gains: str | None = None
    current_bandwidth: float | None = None
    speed_bandwidth: float | None = None
    current_limit: float | None = None
    u_dc: float | None = None
    n_substeps: int = 10
    unroll_substeps: bool = False
    estimator: str | None = None
    speed_rpm: float | None = None
    load_nm: float | None = None
    load_time_s: float | None = None
    duration_s: float | None = None
    current_threshold_a: float | None = None
    tracking_threshold_rpm: float = 10.0
    machine: str = "three-phase"
    control: str | None = None
    pwm: str | None = None
    linear_stability: bool = False

    def __post_init__(self):
        if self.estimator is not None:
            from pmsmjax.estimators.registry import check_observer_name

            check_observer_name(self.estimator)
        if self.machine not in PHASES:
            raise ParameterError(
                f"study machine must be 'three-phase', 'six-phase' or 'five-phase', got {self.machine!r}."
            )
        for f in ("current_limit", "u_dc"):
            if getattr(self, f) is not None:
                _check_number(f, getattr(self, f), positive=True)
        spec = self.spec  # the drive file, checked (before anything compiles)
        resolved = {
            "current_bandwidth": spec.control["current_bandwidth_rad_s"],
            "speed_bandwidth": spec.control["speed_bandwidth_rad_s"],
            "current_limit": spec.current_limit_a,
            "u_dc": spec.u_dc_v,
            **spec.scenario,
        }
        for f, value in resolved.items():
            if getattr(self, f) is None:
                object.__setattr__(self, f, value)
        if self.decimate is None and isinstance(self.duration_s, (int, float)) and self.duration_s > 0:
            n = self.n_periods
            object.__setattr__(self, "decimate", max(d for d in range(1, DECIMATE_AT_MOST + 1) if n % d == 0))
        if self.parameters is None:
            tolerances = default_tolerances(spec) if self.estimator is None else SENSORLESS_TOLERANCES
            default = {k: {"distribution": "uniform", "tolerance": v} for k, v in tolerances.items()}
            default.update(operating_parameters(spec))
            object.__setattr__(self, "parameters", default)
        for f in ("n", "chunk_size", "decimate", "n_substeps"):
            v = getattr(self, f)
            if f == "chunk_size" and v == "auto":
                continue
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                also = ' or "auto"' if f == "chunk_size" else ""
                raise ParameterError(f"study {f} must be an int >= 1{also}, got {v!r}.")
        if isinstance(self.sensitivity_runs, bool) or not isinstance(self.sensitivity_runs, int):
            raise ParameterError(
                f"study sensitivity_runs must be an int >= 0, got {self.sensitivity_runs!r}."
            )
        if self.sensitivity_runs < 0:
            raise ParameterError(f"study sensitivity_runs must be >= 0, got {self.sensitivity_runs}.")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ParameterError(f"study seed must be an int >= 0, got {self.seed!r}.")
        if self.sampling not in SAMPLING:
            raise ParameterError(
                f"study sampling must be one of {', '.join(SAMPLING)}, got {self.sampling!r}."
            )
        if self.nonphysical not in ("refuse", "clip"):
            raise ParameterError(f"study nonphysical must be 'refuse' or 'clip', got {self.nonphysical!r}.")
        if not isinstance(self.unroll_substeps, bool):
            raise ParameterError(
                f"study unroll_substeps must be true or false, got {self.unroll_substeps!r}."
            )
        if not self.parameters:
            raise ParameterError("the study varies no parameter: give at least one [parameters.NAME] table.")
        for f in ("current_bandwidth", "speed_bandwidth", "current_limit", "u_dc", "duration_s"):
            _check_number(f, getattr(self, f), positive=True)
        for f in ("speed_rpm", "load_nm"):
            _check_number(f, getattr(self, f))
        _check_number("tracking_threshold_rpm", self.tracking_threshold_rpm, positive=True)
        if self.current_threshold_a is not None:
            _check_number("current_threshold_a", self.current_threshold_a, positive=True)
        if self.machine == "three-phase" and self.control not in (None, "pi"):
            raise ParameterError(
                f"study control {self.control!r}: the three-phase study runs the PI book drive; other "
                "controls are for machine = 'six-phase'."
            )
        if self.machine == "three-phase" and self.pwm is not None:
            raise ParameterError("study pwm applies to machine = 'six-phase' only.")
        if self.machine != "three-phase" and self.estimator is not None:
            raise ParameterError(
                f"study estimator {self.estimator!r} applies to the three-phase drive only (the chapter 5 "
                "observers are three-phase); drop it or set machine = 'three-phase'."
            )
        if self.machine != "three-phase" and self.unroll_substeps:
            raise ParameterError(
                "study unroll_substeps applies to the three-phase drive only (the six-phase dq model "
                "integrates its planes itself); drop it or set machine = 'three-phase'."
            )
        if not 0 < self.load_time_s < self.duration_s:
            raise ParameterError(
                f"load_time_s = {self.load_time_s} s must lie inside the run "
                f"(0, duration_s = {self.duration_s} s)."
            )
        for name, spec in self.parameters.items():
            if not isinstance(spec, dict):
                raise ParameterError(f"parameter {name}: expected a table, got {spec!r}.")
            unknown = sorted(set(spec) - {"distribution", "tolerance", "sigmas", "nominal"})
            if unknown:
                raise ParameterError(
                    f"parameter {name}: unknown keys {unknown}; "
                    "allowed: distribution, tolerance, sigmas, nominal."
                )
            if spec.get("distribution", "uniform") not in KINDS:
                raise ParameterError(
                    f"parameter {name}: distribution {spec.get('distribution')!r} is unknown; use one of "
                    f"{', '.join(KINDS)}."
                )
            if "tolerance" not in spec:
                raise ParameterError(
                    f"parameter {name}: give its tolerance (relative half-width, 0.2 for +-20 %)."
                )

    @property
    def spec(self) -> DriveSpec:
        """The study's drive file (``motor``, for its machine), ``u_dc`` and ``current_limit`` overriding
        the file's."""
        return drive_spec(
            self.motor,
            n_phases=PHASES[self.machine],
            u_dc_v=self.u_dc,
            max_current_a=self.current_limit,
            flags={"u_dc_v": "study u_dc", "max_current_a": "study current_limit"},
        )

    @property
    def current_threshold(self) -> float:
        """Peak phase current counted as a failure, A."""
        return 1.05 * self.current_limit if self.current_threshold_a is None else self.current_threshold_a

    @property
    def n_periods(self) -> int:
        """Control periods simulated per draw: ``duration_s / Ts``, rounded."""
        return int(round(self.duration_s / self.spec.Ts))


def _check_number(name, v, positive=False):
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ParameterError(f"study {name} must be a finite number, got {v!r}.")
    if positive and v <= 0:
        raise ParameterError(f"study {name} must be > 0, got {v}.")


def default_tolerances(spec: DriveSpec) -> dict[str, float]:
    """``{study parameter: relative half-width}``: the drive file's ``[tolerances]`` (in the file layout's
    order), or [`DEFAULT_TOLERANCES`][tuning.montecarlo.study.DEFAULT_TOLERANCES] for a file without one."""
    if not spec.tolerances:
        return dict(DEFAULT_TOLERANCES)
    out = {}
    for k in TABLES["tolerances"]:
        if k not in spec.tolerances:
            continue
        if k in SENSOR_TOLERANCE_PARAMETERS:  # one parameter per sensor, drawn independently
            for i in range(len(spec.sensor["current_offset_a"])):
                out[f"{SENSOR_TOLERANCE_PARAMETERS[k]}[{i}]"] = spec.tolerances[k]
        else:
            out[TOLERANCE_PARAMETERS[k]] = spec.tolerances[k]
    return out


def operating_parameters(spec: DriveSpec) -> dict[str, dict]:
    """The drive file's ``[operating]`` bands as study parameters, each uniform over its band ``[low, high]``
    (nominal its middle, tolerance its half-width over the middle): ``thermal.initial_k`` (the winding
    temperature at the start of a run) and ``thermal.ambient_k`` in kelvin (so that the middle is never 0),
    ``bridge.u_dc`` in V."""
    from pmsmjax.units import celsius_to_kelvin

    out = {}
    for key, name, to_si in (
        ("winding_temperature_c", "thermal.initial_k", celsius_to_kelvin),
        ("ambient_c", "thermal.ambient_k", celsius_to_kelvin),
        ("u_dc_v", "bridge.u_dc", float),
    ):
        if key in spec.operating:
            low, high = (to_si(v) for v in spec.operating[key])
            middle = 0.5 * (low + high)
            out[name] = {
                "distribution": "uniform",
                "nominal": middle,
                "tolerance": (high - low) / (2 * middle),
            }
    return out


def _with_gains(drive: Drive, path) -> Drive:
    """``drive`` with the gains file ``path``, each gain checked against the drive's own
    ([`check_gains`][tuning.parameters.check_gains])."""
    gains = read_gains_toml(path)
    check_gains(drive, gains, f"gains file {path}")
    return apply_gains(drive, gains)


def build_drive(study: Study) -> Drive:
    """The nominal drive of ``study``: the drive file's drive
    ([`pmsmjax.assemble.spec_drive`][pmsmjax.assemble.spec_drive]) with the study's bandwidths and sub-steps,
    tuned gains if given, and the observer with the file's I/f start for a sensorless study."""
    from pmsmjax.assemble import spec_drive, startup_options, with_map_aware_estimator

    spec = study.spec
    options = dict(
        current_bandwidth=study.current_bandwidth,
        speed_bandwidth=study.speed_bandwidth,
        n_substeps=study.n_substeps,
    )
    if study.machine in ("six-phase", "five-phase"):
        five = study.machine == "five-phase"
        drive = spec_drive(
            spec, study.control or "vsd", pwm=study.pwm or ("near-four-vector" if five else "four-vector"),
            **options,
        )  # fmt: skip
        return drive if study.gains is None else _with_gains(drive, study.gains)
    drive = spec_drive(spec, "pi", **options)
    if study.unroll_substeps:
        unrolled = AveragedBridge(drive.bridge.u_dc, unroll_substeps=True)
        # keep the drive file's dead time and device drop (None without them)
        unrolled = set_leaves(unrolled, ["voltage_error"], [drive.bridge.voltage_error])
        drive = set_leaves(drive, ["bridge"], [unrolled])
    drive = drive if study.gains is None else _with_gains(drive, study.gains)
    if study.estimator is not None:  # the observer's model: the nominal motor (the plant is varied)
        drive = presets.with_observer(
            drive, study.estimator, drive.machine.motor, startup=True, startup_options=startup_options(spec)
        )
        if spec.flux_map is not None:  # the observer reads the file's map, as demo and compare run it
            drive = with_map_aware_estimator(spec, drive)
    return drive


def nominal_value(study: Study, drive: Drive, name: str) -> float:
    """The nominal value of parameter ``name`` (see the module docstring for the names)."""
    check_name(drive, name)
    if name.startswith("scenario."):
        return float(getattr(study, name.split(".", 1)[1]))
    return float(_leaf(drive, name))


def check_name(drive: Drive, name: str) -> None:
    """Raise [`ParameterError`][pmsmjax.spec.validation.ParameterError] unless `name` is a parameter a study
    may vary on `drive` (a motor field, ``bridge.u_dc``, a scenario field, a current sensor's offset or gain,
    or a controller leaf), listing them."""
    fields = MOTOR_FIELDS + drive.machine.motor.leakage_fields
    if getattr(drive.machine.motor, "load_inertia", None) is not None:
        fields += SHAFT_FIELDS
    allowed = [f"motor.{f}" for f in fields] + ["bridge.u_dc"] + [f"scenario.{f}" for f in SCENARIO_FIELDS]
    sensors = tuple(SENSOR_TOLERANCE_PARAMETERS.values())
    allowed += [n for n in array_leaf_names(drive) if n.startswith(sensors)]
    if drive.thermal is not None:
        allowed += ["thermal.initial_k", "thermal.ambient_k"]
    controller = [n for n in array_leaf_names(drive) if n.startswith("controller.") and ".model." not in n]
    if name not in allowed and name not in controller:
        raise ParameterError(
            f"unknown study parameter {name!r}: choose from {allowed} or a controller leaf {controller}."
        )


def _drive_path(name: str) -> str:
    """The dotted path from the drive of a study parameter (``motor.R`` is ``machine.motor.R``)."""
    return "machine." + name if name.startswith("motor.") else name


def _leaf(drive: Drive, name: str):
    return get_leaf(drive, _drive_path(name))


def distributions(study: Study, drive: Drive) -> dict[str, Distribution]:
    """The study's distributions with their nominal values filled in from the drive/scenario."""
    out = {}
    for name, spec in study.parameters.items():
        nominal = spec.get("nominal", None)
        out[name] = Distribution(
            kind=spec.get("distribution", "uniform"),
            nominal=nominal_value(study, drive, name) if nominal is None else nominal,
            tolerance=spec["tolerance"],
            sigmas=spec.get("sigmas", 3.0),
            absolute=name.startswith(ABSOLUTE_PARAMETERS),
        )
        out[name].check(f"parameter {name}")
    return out


def apply_sample(drive: Drive, study: Study, names: tuple[str, ...], values) -> tuple[Drive, Scenario]:
    """The drive and scenario of one run: ``values (P,)`` (may be traced) for the parameters ``names``."""
    drive_names = [n for n in names if not n.startswith("scenario.")]
    if drive_names:
        drive = set_leaves(
            drive,
            [_drive_path(n) for n in drive_names],
            [values[names.index(n)].astype(drive.machine.motor.R.dtype) for n in drive_names],
        )
    scen = {f: getattr(study, f) for f in SCENARIO_FIELDS}
    for n in names:
        if n.startswith("scenario."):
            scen[n.split(".", 1)[1]] = values[names.index(n)]
    dtype = drive.machine.motor.R.dtype
    scenario = Scenario(
        duration_s=study.duration_s,
        speed_ref=Profile(
            jnp.zeros(1, dtype),
            jnp.reshape(rpm_to_rad_s(jnp.asarray(scen["speed_rpm"], dtype)), (1,)),
            jnp.zeros(1, dtype),
        ),
        load_torque=Profile(
            jnp.asarray([0.0, study.load_time_s], dtype),
            jnp.stack([jnp.zeros((), dtype), jnp.asarray(scen["load_nm"], dtype)]),
            jnp.zeros(2, dtype),
        ),
    )
    return drive, scenario
