"""Observers side by side (``pmsmjax compare --estimator``): the chapter 5 observers on the book FOC drive,
sensorless from standstill with the I/f start, and the chapter 6 estimators (HF injection, the hybrid) on
the salient book motor with d-axis saturation, each in a scenario it is made for. On a drive file with a
flux map the chapter 5 observers run the file's own drive instead (its map's plant, current loop and field
weakening, its I/f start), each observer reading the map
([`map_observer_drive`][pmsmjax.jobs.estimator_comparison.map_observer_drive]), and the low-speed sweep is
scaled to the drive ([`LowSpeedSweep.for_drive`][pmsmjax.jobs.estimator_comparison.LowSpeedSweep.for_drive]).

Each estimator's run gives the figures of the controller comparison
([`pmsmjax.jobs.control_comparison.run_control`][pmsmjax.jobs.control_comparison.run_control]) on the book
scenario, or those of [`run_estimator_scenario`][pmsmjax.jobs.estimator_comparison.run_estimator_scenario] on
the fixed ones, plus the observer's
([`pmsmjax.analysis.observer_errors.observer_errors`][pmsmjax.analysis.observer_errors.observer_errors]) and,
on the book scenario, the lowest speed held under load
([`LowSpeedSweep`][pmsmjax.jobs.estimator_comparison.LowSpeedSweep]).
[`estimator_table`][pmsmjax.jobs.estimator_comparison.estimator_table] lays them out as Markdown.
"""

import dataclasses
import math
import re

import jax
import numpy as np

from pmsmjax import presets
from pmsmjax.analysis import metrics
from pmsmjax.analysis.observer_errors import observer_errors, speed_held
from pmsmjax.assemble import with_parts
from pmsmjax.drive import Drive
from pmsmjax.inverters.switching import SwitchingBridge
from pmsmjax.jobs.control_comparison import ControllerCompareSettings, run_control, window_periods
from pmsmjax.machines.motor import PMSMParameters
from pmsmjax.simulate import check_simulation, simulate
from pmsmjax.spec.validation import ParameterError
from pmsmjax.units import rad_s_to_rpm

#: Speeds (r/min) of the low-speed sweep under load, highest first.
LOW_SPEED_SWEEP_RPM = (500.0, 300.0, 200.0, 150.0, 100.0, 70.0, 50.0, 30.0, 20.0, 10.0, 5.0, 2.0)
#: The book drive's rated speed (r/min) and scenario duration (s) that
#: [`LowSpeedSweep`][pmsmjax.jobs.estimator_comparison.LowSpeedSweep]'s defaults are written for; a drive
#: file's sweep is scaled by its own over these
#: ([`LowSpeedSweep.for_drive`][pmsmjax.jobs.estimator_comparison.LowSpeedSweep.for_drive]).
BOOK_SWEEP_RATED_SPEED_RPM = 1000.0
BOOK_SWEEP_SCENARIO_S = 0.4


@dataclasses.dataclass(frozen=True)
class LowSpeedSweep:
    """The sweep behind ``lowest_held_rpm``: one run per speed in `speeds_rpm`, each from standstill
    (I/f start) to `start_rpm`, the load `load_nm` stepped on at `load_time_s`, then the reference ramped
    from `start_rpm` down to the swept speed over [`ramp_start_s`, `ramp_end_s`], held to `duration_s`;
    judged from `judge_from_s` to the end
    ([`pmsmjax.analysis.observer_errors.speed_held`][pmsmjax.analysis.observer_errors.speed_held]).

    With the observer's model equal to the plant and no noise, a fundamental-model observer sees the
    small back-EMF exactly and holds very low speeds; what limits it on a real drive is model error. So
    the sweep is also run with the plant's stator resistance times `hot_r_factor` (1.3: about 75 K of
    copper heating) while the observer and the controller keep the nominal value (None: not run).
    """

    speeds_rpm: tuple = LOW_SPEED_SWEEP_RPM
    start_rpm: float = 500.0
    load_nm: float = 10.0
    load_time_s: float = 0.1
    ramp_start_s: float = 0.15
    ramp_end_s: float = 0.35
    judge_from_s: float = 0.45
    duration_s: float = 0.6
    hot_r_factor: float | None = 1.3

    def scenario(self, speed_rpm: float):
        """The [`Scenario`][pmsmjax.scenarios.Scenario] of one swept speed `speed_rpm` (r/min): the ramp from
        `start_rpm` down to it and the load step (class docstring)."""
        from pmsmjax.scenarios import Profile, Scenario
        from pmsmjax.units import rpm_to_rad_s

        return Scenario(
            duration_s=self.duration_s,
            speed_ref=Profile.ramp(
                self.ramp_start_s, self.ramp_end_s, rpm_to_rad_s(self.start_rpm), rpm_to_rad_s(speed_rpm)
            ),
            load_torque=Profile.step(self.load_time_s, 0.0, self.load_nm),
        )

    @classmethod
    def for_drive(cls, spec, load_nm: float) -> "LowSpeedSweep":
        """The book sweep on the drive file ``spec``: every speed (the swept ones and the start) times the
        file's rated speed over the book's 1000 r/min, every time times the file's ``[scenario]`` duration
        over the book's 0.4 s, under ``load_nm`` (N m; the compared scenario's load, the file's by
        default). Why scaled: a back-EMF observer's difficulty is the back-EMF against the voltage errors,
        which goes with the speed as a share of the rated one, and a drive with more inertia per torque
        needs the book's times stretched as its scenario is (saturated-ipm: 3000 r/min rated, 0.4 s: the
        speeds 1500 down to 6 r/min, the book's times)."""
        speed = spec.ratings["rated_speed_rpm"] / BOOK_SWEEP_RATED_SPEED_RPM
        time = spec.scenario["duration_s"] / BOOK_SWEEP_SCENARIO_S
        book = cls()
        return cls(
            speeds_rpm=tuple(speed * s for s in book.speeds_rpm),
            start_rpm=speed * book.start_rpm,
            load_nm=load_nm,
            load_time_s=time * book.load_time_s,
            ramp_start_s=time * book.ramp_start_s,
            ramp_end_s=time * book.ramp_end_s,
            judge_from_s=time * book.judge_from_s,
            duration_s=time * book.duration_s,
        )


def observer_drive(
    name: str, motor: PMSMParameters | None = None, bridge: str = "averaged", startup: bool = True
) -> Drive:
    """The book FOC drive with observer ``name``
    ([`pmsmjax.estimators.OBSERVERS`][pmsmjax.estimators.catalogue.OBSERVERS], design-rule gains for
    ``motor``) and the I/f start from standstill, on ``bridge``."""
    drive = presets.sensorless_drive(name, motor, startup=startup)
    if bridge == "switching":
        drive = with_parts(drive, {"bridge": SwitchingBridge(drive.bridge.u_dc)})
    return drive


def map_observer_drive(spec, name: str, bridge: str = "averaged", observer_model: str = "map") -> Drive:
    """The FOC drive of the drive file ``spec`` ([`pmsmjax.assemble.assemble`][pmsmjax.assemble.assemble]: on
    a flux map, the map's plant, current loop and field weakening) sensorless on observer ``name`` with the
    file's I/f start; the observer reads the map (``observer_model="map"``,
    [`pmsmjax.assemble.map_aware`][pmsmjax.assemble.map_aware]) or keeps the file's constant ``L_d``,
    ``L_q``, ``psi_f`` (``"constant"``); on ``bridge`` (the switching one as in the control comparison,
    [`pmsmjax.jobs.control_comparison.compared_drive`][pmsmjax.jobs.control_comparison.compared_drive])."""
    from pmsmjax.assemble import assemble

    drive = assemble(spec, "pi", estimator=name, observer_model=observer_model)
    if bridge == "switching":
        drive = with_parts(drive, {"bridge": SwitchingBridge(drive.bridge.u_dc)})
    return drive


def check_injection_region(spec, names, load_nm: float, flag: str = "--load-nm") -> None:
    """Refuse, in one line, chapter 6 estimators on the drive file ``spec`` with a flux map whose map has no
    injection region, and a load ``load_nm`` (N m; ``flag`` says where it came from) beyond the region for
    HF injection alone (the hybrid is left to run: its observer takes over above its speed band)
    ([`pmsmjax.estimators.injection_region`][pmsmjax.estimators.injection_region]; NumPy)."""
    from pmsmjax.estimators.injection_region import check_injection_load, spec_injection_region

    region = spec_injection_region(spec)
    for name in names:
        if name.startswith("hfi-"):
            check_injection_load(region, load_nm, flag, name)


def map_chapter6_drive(spec, name: str, bridge: str = "averaged") -> Drive:
    """The FOC drive of the drive file ``spec`` with a flux map (its plant, current loop and field
    weakening, [`pmsmjax.assemble.assemble`][pmsmjax.assemble.assemble]) sensorless on the injection or
    hybrid estimator ``name``, designed on the map's incremental inductances at no load
    ([`map_injection_design`][pmsmjax.assemble.map_injection_design]) and map-aware
    ([`map_aware`][pmsmjax.assemble.map_aware]: the cross-saturation angle taken out); no I/f start
    (injection sees the rotor at standstill); on ``bridge``."""
    from pmsmjax.assemble import assemble, map_injection_design, spec_motor, with_map_aware_estimator

    model, options = map_injection_design(spec, name, spec_motor(spec))
    drive = presets.with_observer(assemble(spec, "pi"), name, model, options, startup=False)
    drive = with_map_aware_estimator(spec, drive)
    if bridge == "switching":
        drive = with_parts(drive, {"bridge": SwitchingBridge(drive.bridge.u_dc)})
    return drive


def handover_settled_s(drive: Drive) -> float:
    """When the angle error of ``drive``'s I/f start is judged from, s: the end of its hand-over (the I/f
    ramp at ``handover_speed + blend_speed``) plus the margin the book drive has between its own hand-over
    end and
    [`pmsmjax.analysis.observer_errors.CONVERGED_AFTER_S`][pmsmjax.analysis.observer_errors.CONVERGED_AFTER_S]
    (50 ms - 26.2 ms). Why: a drive file's start-up may last longer than the book's (saturated-ipm: 68 ms of
    ramp and blend, so 91.8 ms), and the figures after convergence would count the blend itself."""
    from pmsmjax.analysis.observer_errors import CONVERGED_AFTER_S
    from pmsmjax.assemble import STARTUP_DEFAULTS

    end = lambda accel, handover, blend: (handover + blend) / accel
    book = STARTUP_DEFAULTS
    margin = CONVERGED_AFTER_S - end(book["accel"], book["handover_speed"], book["blend_speed"])
    e = drive.estimator
    return float(end(e.accel, e.handover_speed, e.blend_speed)) + margin


def low_speed_sweep(
    drive: Drive,
    sweep: LowSpeedSweep = LowSpeedSweep(),
    r_factor: float = 1.0,
    converged_after_s: float | None = None,
) -> dict:
    """Run ``drive`` (its plant's R times ``r_factor``) through every speed of ``sweep`` (one batched
    simulation); returns ``{"runs": [{speed_rpm, held, ...}], "lowest_held_rpm"}``: the lowest swept
    speed such that it and every higher swept speed were held (None if the highest was not).
    ``converged_after_s``: lock is judged from this time, s (None: the book's
    [`pmsmjax.analysis.observer_errors.CONVERGED_AFTER_S`][pmsmjax.analysis.observer_errors.CONVERGED_AFTER_S])."""
    from pmsmjax.scenarios import stack_scenarios

    if r_factor != 1.0:
        drive = with_parts(drive, {"machine.motor.R": drive.machine.motor.R * r_factor})

    scenarios = [sweep.scenario(s) for s in sweep.speeds_rpm]
    check_simulation(drive, scenarios[0])
    batch = stack_scenarios(scenarios)
    traces = jax.block_until_ready(jax.vmap(simulate, in_axes=(None, 0))(drive, batch))
    runs, lowest = [], None
    for i, speed in enumerate(sweep.speeds_rpm):
        trace = jax.tree.map(lambda x, i=i: np.asarray(x[i]), traces)
        settled = {} if converged_after_s is None else {"converged_after_s": converged_after_s}
        run = {"speed_rpm": float(speed), **speed_held(trace, drive.Ts, sweep.judge_from_s, **settled)}
        runs.append(run)
    for run in runs:  # highest first: stop at the first speed not held
        if not run["held"]:
            break
        lowest = run["speed_rpm"]
    return {"runs": runs, "lowest_held_rpm": lowest, "r_factor": r_factor}


#: The scenarios of ``compare --estimator`` (``scenario=`` of
#: [`compare_estimators`][pmsmjax.jobs.estimator_comparison.compare_estimators]): name -> (description,
#: estimator families it suits). ``book``: `_scenario` of the settings; the others are fixed runs
#: ([`estimator_scenario`][pmsmjax.jobs.estimator_comparison.estimator_scenario]) at low speed or through
#: zero, where HF injection works.
ESTIMATOR_SCENARIOS = {
    "book": (
        "speed step from standstill, then the load step (the settings' book scenario)",
        ("ch5", "hybrid"),
    ),
    "standstill": ("speed reference 0, the load stepped on at 0.1 s, 0.8 s", ("injection", "hybrid")),
    "slow-reversal": (
        "0 -> 60 r/min (0.05-0.15 s) -> -60 r/min (0.3-0.6 s), the load stepped on at 0.1 s, 0.8 s",
        ("injection", "hybrid"),
    ),
    "reversal": (
        "-1000 r/min from standstill, 5 N m from 0.15 s, step to +1000 r/min at 0.3 s, 0.7 s",
        ("hybrid",),
    ),
}

#: Default initial rotor angle of the chapter 6 runs, electrical degrees off the estimators' initial
#: estimate (0): the injection methods must find the d axis, not start on it (benchmarks/hfi_accuracy.py).
CHAPTER6_INITIAL_ANGLE_DEG = 30.0


def estimator_family(name: str) -> str:
    """``"ch5"`` ([`pmsmjax.estimators.OBSERVERS`][pmsmjax.estimators.catalogue.OBSERVERS]), ``"injection"``
    (``INJECTION_OBSERVERS``: angle modulo pi) or ``"hybrid"`` (``HYBRID_OBSERVERS``)."""
    from pmsmjax.estimators.registry import HYBRID_OBSERVERS, INJECTION_OBSERVERS, check_observer_name

    check_observer_name(name)
    return "injection" if name in INJECTION_OBSERVERS else "hybrid" if name in HYBRID_OBSERVERS else "ch5"


def check_estimator_scenario(names, scenario: str) -> None:
    """Refuse a comparison that makes no sense: an unknown scenario, chapter 5 observers with chapter 6
    estimators (different motors and start-ups), or an estimator in a scenario it is not made for."""
    if scenario not in ESTIMATOR_SCENARIOS:
        raise ParameterError(
            f"--scenario {scenario!r}: unknown; choose from {', '.join(ESTIMATOR_SCENARIOS)}."
        )
    families = {n: estimator_family(n) for n in names}
    ch5 = [n for n, f in families.items() if f == "ch5"]
    ch6 = [n for n, f in families.items() if f != "ch5"]
    if ch5 and ch6:
        raise ParameterError(
            f"--estimator mixes chapter 5 observers ({', '.join(ch5)}) with chapter 6 injection estimators "
            f"({', '.join(ch6)}): they need different motors (surface vs salient) and start-ups; compare "
            "them in two runs."
        )
    suits = ESTIMATOR_SCENARIOS[scenario][1]
    wrong = [n for n, f in families.items() if f not in suits]
    if wrong:
        fit = [s for s, (_, fams) in ESTIMATOR_SCENARIOS.items() if all(families[n] in fams for n in names)]
        why = {
            "ch5": "the chapter 5 observers start with I/f and are compared on the book scenario",
            "injection": "HF injection alone is a standstill and low-speed method (no polarity, the carrier "
            "fades out at speed; the hybrid covers the whole range)",
            "hybrid": "",
        }[families[wrong[0]]]
        raise ParameterError(
            f"--scenario {scenario} does not suit {', '.join(wrong)}: {why}; give --scenario "
            f"{' or '.join(fit) if fit else 'in two runs'}."
        )


def estimator_scenario(scenario: str, load_nm: float):
    """The fixed chapter 6 scenarios of
    [`ESTIMATOR_SCENARIOS`][pmsmjax.jobs.estimator_comparison.ESTIMATOR_SCENARIOS] (all but ``book``) with the
    load ``load_nm`` (N m; ``reversal`` keeps its 5 N m)."""
    from pmsmjax.jobs.hybrid_runs import hybrid_scenarios
    from pmsmjax.scenarios import Profile, Scenario
    from pmsmjax.units import rpm_to_rad_s

    w60 = rpm_to_rad_s(60.0)
    load = Profile.step(0.1, 0.0, load_nm)
    if scenario == "standstill":
        return Scenario(0.8, Profile.piecewise([0.0, 0.8], [0.0, 0.0], "linear"), load)
    if scenario == "slow-reversal":
        t = [0.0, 0.05, 0.15, 0.3, 0.6, 0.8]
        return Scenario(0.8, Profile.piecewise(t, [0.0, 0.0, w60, w60, -w60, -w60], "linear"), load)
    return hybrid_scenarios()[scenario]


def chapter6_drive(name: str, motor: PMSMParameters | None = None, bridge: str = "averaged") -> Drive:
    """The book FOC drive with the injection or hybrid estimator ``name`` (design rule for ``motor``,
    default the salient book motor), no I/f start (injection sees the rotor at standstill), on the plant
    with d-axis saturation
    ([`pmsmjax.machines.saturated_machine`][pmsmjax.machines.saturation.saturated_machine], defaults), which
    the hybrid's polarity pulses read (at ``i_d = 0`` its inductance is the linear machine's), on
    ``bridge``."""
    from pmsmjax.machines.saturation import saturated_machine

    motor = presets.book_motor(salient=True) if motor is None else motor
    drive = presets.sensorless_drive(name, motor, startup=False)
    drive = with_parts(drive, {"machine": saturated_machine(motor)})
    if bridge == "switching":
        drive = with_parts(drive, {"bridge": SwitchingBridge(drive.bridge.u_dc)})
    return drive


def run_estimator_scenario(drive: Drive, scenario, initial_state) -> dict:
    """Simulate ``drive`` through a fixed scenario
    ([`estimator_scenario`][pmsmjax.jobs.estimator_comparison.estimator_scenario]) from ``initial_state``; its
    figures (ITAE of the speed error, rad s; largest speed deviation from the reference, r/min, after
    [`pmsmjax.analysis.observer_errors.CONVERGED_AFTER_S`][pmsmjax.analysis.observer_errors.CONVERGED_AFTER_S];
    peak phase current, A) and its trace."""
    from pmsmjax.analysis.observer_errors import CONVERGED_AFTER_S

    check_simulation(drive, scenario)
    trace = simulate(drive, scenario, initial_state=initial_state).to_numpy()  # figures in NumPy
    t = np.asarray(trace.t, np.float64)
    w = np.asarray(trace.omega_m, np.float64)
    ref = np.asarray(trace.speed_ref, np.float64)
    after = t >= CONVERGED_AFTER_S - 0.5 * drive.Ts
    error = metrics.tracking_error(ref, w)
    entry = {
        "itae": float(metrics.itae(t, error)),
        "speed_deviation_max_rpm": float(rad_s_to_rpm(np.max(np.abs(error[after])))),
        "final_speed_rpm": float(rad_s_to_rpm(w[-1])),
        "peak_current_a": float(metrics.peak_phase_current(trace.i_abc)),
        "current_limit_a": float(drive.controller.current_limit),
        "control_period_s": drive.Ts,
        "bridge": type(drive.bridge).__name__,
        "operating_point": {"flags": []},
    }
    return {"entry": entry, "trace": trace, "window": None}


def compare_estimators(
    names,
    motor: PMSMParameters | None = None,
    settings: ControllerCompareSettings | None = None,
    sweep: LowSpeedSweep | None = LowSpeedSweep(),
    progress=None,
    scenario: str = "book",
    initial_angle_deg: float | None = None,
    spec=None,
    observer_model: str = "map",
) -> dict:
    """Run the book FOC drive sensorless with each named estimator through ``scenario``
    ([`ESTIMATOR_SCENARIOS`][pmsmjax.jobs.estimator_comparison.ESTIMATOR_SCENARIOS]; refused where it makes no
    sense, [`check_estimator_scenario`][pmsmjax.jobs.estimator_comparison.check_estimator_scenario]).

    Chapter 5 observers ([`pmsmjax.estimators.OBSERVERS`][pmsmjax.estimators.catalogue.OBSERVERS]) start from
    standstill with I/f; the chapter 6 estimators (``hfi-rotating``, ``hfi-pulsating``, ``hybrid``) run
    [`chapter6_drive`][pmsmjax.jobs.estimator_comparison.chapter6_drive] (default motor the salient book
    motor) with the rotor ``initial_angle_deg`` electrical degrees off their initial estimate (default 0 for
    chapter 5, [`CHAPTER6_INITIAL_ANGLE_DEG`][pmsmjax.jobs.estimator_comparison.CHAPTER6_INITIAL_ANGLE_DEG]
    for chapter 6).

    Each entry holds, on ``book``, the figures of [`run_control`][pmsmjax.jobs.control_comparison.run_control]
    (rise, dip, ITAE, THD, ripple, ...), on the fixed scenarios those of
    [`run_estimator_scenario`][pmsmjax.jobs.estimator_comparison.run_estimator_scenario]; and the observer's
    ([`pmsmjax.analysis.observer_errors.observer_errors`][pmsmjax.analysis.observer_errors.observer_errors]:
    angle error RMS/max after convergence in electrical degrees, **modulo pi for the injection estimators**
    (``angle_modulo``), speed estimation error RMS, speed tracking error RMS, ``lock_lost``, judged on the
    angle alone off the book scenario), plus, on ``book`` unless ``sweep`` is None, ``lowest_held_rpm`` under
    ``sweep.load_nm`` and the sweep's runs
    ([`low_speed_sweep`][pmsmjax.jobs.estimator_comparison.low_speed_sweep]), and ``lowest_held_rpm_hot_r``
    with the plant's R off the observer's by ``sweep.hot_r_factor``. Returns the layout of
    [`compare_controllers`][pmsmjax.jobs.control_comparison.compare_controllers] (``windows`` None off the
    book scenario). ``settings`` None: the default
    [`ControllerCompareSettings`][pmsmjax.jobs.control_comparison.ControllerCompareSettings].

    ``spec``: a drive file ([`pmsmjax.spec.drive_spec.DriveSpec`][pmsmjax.spec.drive_spec.DriveSpec]) whose
    own drive runs each chapter 5 observer instead of the book drive
    ([`map_observer_drive`][pmsmjax.jobs.estimator_comparison.map_observer_drive] with ``observer_model``;
    ``motor`` is then unused); the chapter 6 estimators run the file's own drive on its flux map
    ([`map_chapter6_drive`][pmsmjax.jobs.estimator_comparison.map_chapter6_drive]) and are refused on a file
    without one (their comparison runs its own salient motor). The result's settings then name the drive,
    the observer model and the time the figures after convergence start from
    ([`handover_settled_s`][pmsmjax.jobs.estimator_comparison.handover_settled_s] of the file's I/f start).
    """
    settings = ControllerCompareSettings() if settings is None else settings
    settings.check()
    check_estimator_scenario(names, scenario)
    families = {name: estimator_family(name) for name in names}
    chapter6 = any(f != "ch5" for f in families.values())
    if initial_angle_deg is None:
        initial_angle_deg = CHAPTER6_INITIAL_ANGLE_DEG if chapter6 else 0.0
    if spec is not None and chapter6:
        if spec.flux_map is None:
            raise ParameterError(
                f"{', '.join(n for n in names if families[n] != 'ch5')}: the chapter 6 comparison runs "
                "the salient book motor with its d-axis saturation, or a drive file's own drive on its "
                f"flux map; {spec.source} has none: compare these without it."
            )
        drives = {name: map_chapter6_drive(spec, name, settings.bridge) for name in names}
    elif spec is not None:
        drives = {name: map_observer_drive(spec, name, settings.bridge, observer_model) for name in names}
    else:
        build = chapter6_drive if chapter6 else observer_drive
        drives = {name: build(name, motor, settings.bridge) for name in names}
    if scenario == "book":
        for drive in drives.values():
            window_periods(drive, settings)
        fixed = None
    else:
        fixed = estimator_scenario(scenario, settings.load_nm)
    result = {"settings": dataclasses.asdict(settings), "controllers": {}, "traces": {}, "windows": {}}
    result["settings"]["sweep"] = None if sweep is None or fixed is not None else dataclasses.asdict(sweep)
    result["settings"]["scenario"] = scenario
    result["settings"]["initial_angle_deg"] = initial_angle_deg
    # the book comparison's settings stay as they were; a drive file's I/f start has its own duration
    settled = {}
    if spec is not None and chapter6:
        result["settings"]["drive"] = spec.source
        result["settings"]["observer_model"] = "map"
    elif spec is not None:
        result["settings"]["drive"] = spec.source
        result["settings"]["observer_model"] = observer_model if spec.flux_map is not None else None
        settled = {"converged_after_s": handover_settled_s(next(iter(drives.values())))}
        result["settings"].update(settled)
    for name, drive in drives.items():
        start = drive.init(theta_e=math.radians(initial_angle_deg))
        if fixed is None:
            run = run_control(name, drive, settings, start)
        else:
            run = run_estimator_scenario(drive, fixed, start)
        modulo_pi = families[name] == "injection"
        # off the book scenario the speed reference is (near) zero: lock is judged on the angle alone
        errors = observer_errors(
            run["trace"], drive.Ts, modulo_pi=modulo_pi, speed_lock=fixed is None, **settled
        )
        run["entry"].update(errors)
        run["entry"]["observer"] = name
        if sweep is not None and fixed is None:
            swept = low_speed_sweep(drive, sweep, **settled)
            run["entry"]["lowest_held_rpm"] = swept["lowest_held_rpm"]
            run["entry"]["low_speed_runs"] = swept["runs"]
            if sweep.hot_r_factor is not None:
                hot = low_speed_sweep(drive, sweep, sweep.hot_r_factor, **settled)
                run["entry"]["lowest_held_rpm_hot_r"] = hot["lowest_held_rpm"]
                run["entry"]["low_speed_runs_hot_r"] = hot["runs"]
        result["controllers"][name] = run["entry"]
        result["traces"][name] = run["trace"]
        result["windows"][name] = run["window"]
        if progress:
            progress(estimator_row(name, run["entry"]))
    return result


#: Columns of the observer table: (header, key, format).
ESTIMATOR_COLUMNS = (
    ("observer", "observer", "{:12s}"),
    ("angle RMS deg", "angle_error_rms_deg", "{:13.3f}"),
    ("angle max deg", "angle_error_max_deg", "{:13.3f}"),
    ("angle modulo", "angle_modulo", "{!s:12s}"),
    ("speed est RMS r/min", "speed_error_rms_rpm", "{:19.3f}"),
    ("ITAE rad s", "itae", "{:10.4f}"),
    ("dip r/min", "dip_rpm", "{:9.1f}"),
    ("max speed dev r/min", "speed_deviation_max_rpm", "{:19.1f}"),
    ("lock lost", "lock_lost", "{!s:9s}"),
    ("lowest held r/min", "lowest_held_rpm", "{!s:17s}"),
    ("lowest held, hot R", "lowest_held_rpm_hot_r", "{!s:18s}"),
)


def estimator_row(name: str, entry: dict) -> str:
    """One row of the observer table
    ([`ESTIMATOR_COLUMNS`][pmsmjax.jobs.estimator_comparison.ESTIMATOR_COLUMNS])."""
    cells = []
    for _, key, fmt in ESTIMATOR_COLUMNS:
        value = name if key == "observer" else entry.get(key)
        if isinstance(value, float) and key.startswith("lowest_held"):
            value = f"{value:g}"
        if value is None:  # a figure of the other kind of scenario (dip: book; deviation: fixed ones)
            cells.append("-".rjust(int(re.search(r"\d+", fmt).group())))
            continue
        cells.append(fmt.format(value))
    return "  ".join(cells)


def estimator_table(result: dict) -> str:
    """The observer table of [`compare_estimators`][pmsmjax.jobs.estimator_comparison.compare_estimators]'s
    result, as Markdown."""
    head = "| " + " | ".join(h for h, _, _ in ESTIMATOR_COLUMNS) + " |"
    rule = "|" + "|".join("---" for _ in ESTIMATOR_COLUMNS) + "|"
    rows = []
    for name, e in result["controllers"].items():
        cells = [name]
        for _, key, _ in ESTIMATOR_COLUMNS[1:]:
            v = e.get(key)
            cells.append(f"{v:.3g}" if isinstance(v, float) else ("-" if v is None else str(v)))
        rows.append("| " + " | ".join(cells) + " |")
    return "\n".join([head, rule, *rows])
