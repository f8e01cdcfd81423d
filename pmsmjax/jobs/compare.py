"""``pmsmjax compare``: control methods ([`pmsmjax.jobs.control_comparison`][pmsmjax.jobs.control_comparison])
or observers ([`pmsmjax.jobs.estimator_comparison`][pmsmjax.jobs.estimator_comparison]) side by side on a
drive's scenario, from a [`CompareSpec`][pmsmjax.jobs.compare.CompareSpec] to a
[`CompareResult`][pmsmjax.jobs.compare.CompareResult] (compare.json's content, the observer table, the
console's warnings and what the figures need).

Importing this module loads no JAX: [`fitting_speed`][pmsmjax.jobs.compare.fitting_speed] and
[`check_operating_point`][pmsmjax.jobs.compare.check_operating_point] belong to the command's checks before
any work; [`compare_controls`][pmsmjax.jobs.compare.compare_controls] and
[`compare_observers`][pmsmjax.jobs.compare.compare_observers] import the engine when called.
"""

import dataclasses
import time
from collections.abc import Callable, Mapping

from pmsmjax.spec.validation import ParameterError, plain

__all__ = [
    "WINDOW_CYCLES",
    "CompareResult",
    "CompareSpec",
    "check_operating_point",
    "compare_controls",
    "compare_observers",
    "fitting_speed",
]

#: Electrical periods of the ripple and THD window at the end of the run.
WINDOW_CYCLES = 2


@dataclasses.dataclass(frozen=True)
class CompareSpec:
    """What one comparison is asked for (the command's flags, checked, the drive file's scenario filling
    what the user left unset).

    - `drive`: the drive file ([`DriveSpec`][pmsmjax.spec.drive_spec.DriveSpec]); `names`: the control methods
      (or, with `estimators`, the observers) compared; `machine`: ``three-phase``, ``six-phase`` or
      ``five-phase`` (control methods only).
    - `speed_rpm`, `load_nm`, `load_time_s`, `duration_s`: the book scenario (speed step at 0, load step).
    - `bridge`: the voltage-commanding controllers' bridge (``switching`` or ``averaged``);
      `equal_switching_hz`: also run the banded controllers at this mean switching frequency (0: the PWM
      frequency; None: not); `gains`: the tuned gains file, as compare.json reports it.
    - `scenario`: the observers' scenario (``book``, ``standstill``, ``slow-reversal``, ``reversal``);
      `initial_angle_deg`: the chapter 6 estimators' initial rotor angle (None: their default).
    - `observer_model`: on a drive file with a flux map, the observers read the map (``map``, None) or keep
      the file's constant ``L_d``, ``L_q``, ``psi_f`` (``constant``).
    """

    drive: object
    names: tuple[str, ...]
    speed_rpm: float
    load_nm: float
    load_time_s: float
    duration_s: float
    machine: str = "three-phase"
    bridge: str = "switching"
    equal_switching_hz: float | None = None
    gains: str | None = None
    estimators: bool = False
    scenario: str | None = None
    initial_angle_deg: float | None = None
    observer_model: str | None = None


@dataclasses.dataclass(frozen=True)
class CompareResult:
    """What a comparison gives its writer.

    - `report`: compare.json's content.
    - `comparison`: the engine's result
      ([`pmsmjax.jobs.control_comparison.compare_controllers`][pmsmjax.jobs.control_comparison.compare_controllers]
      or
      [`pmsmjax.jobs.estimator_comparison.compare_estimators`][pmsmjax.jobs.estimator_comparison.compare_estimators]:
      settings, figures, traces, ripple windows), which the figures read.
    - `warnings`: a console line per operating-point flag of each run.
    - `table`: compare_estimators.md (the observers only).
    - `angle_errors`: the observers' angle errors for their figure (``t`` s, ``speed_rpm`` r/min of the
      first run, ``errors``: label -> el. degrees, modulo pi for injection without polarity); None for
      the control methods.
    - `load_time_s`: the load step the speed figure marks, s (None: the settings' book scenario's).
    """

    report: dict
    comparison: dict
    warnings: tuple[str, ...]
    table: str | None = None
    angle_errors: Mapping[str, object] | None = None
    load_time_s: float | None = None


def fitting_speed(speed_rpm: float, drive, given: bool) -> tuple[float, str | None]:
    """The run's speed, r/min: the ripple window spans whole electrical periods at the control rate
    ([`pmsmjax.jobs.control_comparison.window_periods`][pmsmjax.jobs.control_comparison.window_periods]). A
    speed from the drive file ``drive`` that does not fit is lowered to the nearest one that does, with a note
    for the console; one the user gave (``given``) is refused with the nearest ones that fit. Returns
    ``(speed, note or None)``; pure Python."""
    from pmsmjax.presets.book_constants import DTC_SAMPLE_PERIOD_S, HYSTERESIS_SAMPLE_PERIOD_S
    from pmsmjax.spec.design_rules import common_period_s, whole_period_speed_rpm

    cycles = WINDOW_CYCLES
    # every control's own period: the comparator drives sample faster than the PWM ones
    period = common_period_s((drive.Ts, HYSTERESIS_SAMPLE_PERIOD_S, DTC_SAMPLE_PERIOD_S))
    fitting = whole_period_speed_rpm(speed_rpm, drive.motor["pole_pairs"], period, cycles)
    if fitting == speed_rpm:
        return speed_rpm, None
    if given:
        slower = whole_period_speed_rpm(0.999 * fitting, drive.motor["pole_pairs"], period, cycles)
        raise ParameterError(
            f"--speed-rpm {plain(speed_rpm)}: {cycles} electrical periods at this speed are not a whole "
            f"number of {plain(period * 1e6)} us (every control's period), which the ripple window needs: "
            "give "
            "e.g. "
            f"{fitting:.6g} or {slower:.6g} r/min."
        )
    note = (
        f"speed {fitting:.6g} r/min instead of the drive file's {plain(speed_rpm)} r/min: the ripple window "
        f"needs {cycles} electrical periods to span whole {plain(period * 1e6)} us (every control's period)"
    )
    return fitting, note


def check_operating_point(drive, speed_rpm: float, load_nm: float, u_dc_flag: str) -> None:
    """Refuse an operating point the drive file ``drive`` cannot hold with i_d = 0
    ([`pmsmjax.spec.steady_state.refuse_unreachable`][pmsmjax.spec.steady_state.refuse_unreachable]): its
    ripple figures would describe saturation. ``u_dc_flag``: the DC-link knob the fix names; pure Python."""
    from pmsmjax.spec.steady_state import refuse_unreachable

    refuse_unreachable(
        drive.motor,
        speed_rpm,
        load_nm,
        drive.u_dc_v,
        drive.voltage_limit_v,  # the default modulator's linear range for the file's phase count
        drive.current_limit_a,
        what="the comparison of ripple and THD",
        u_dc_flag=u_dc_flag,
        current_limit_flag="--current-limit",
    )


def _settings(spec: CompareSpec, **extra):
    from pmsmjax.jobs.control_comparison import ControllerCompareSettings

    settings = ControllerCompareSettings(
        speed_rpm=spec.speed_rpm,
        load_nm=spec.load_nm,
        load_time_s=spec.load_time_s,
        duration_s=spec.duration_s,
        bridge=spec.bridge,
        window_cycles=WINDOW_CYCLES,
        **extra,
    )
    settings.check()
    return settings


def _warnings(result: dict) -> tuple[str, ...]:
    return tuple(
        f"WARNING {name}: {f['flag']}: {f['cause']}; remedy: {f['remedy']}."
        for name, entry in result["controllers"].items()
        for f in entry["operating_point"]["flags"]
    )


def compare_controls(
    spec: CompareSpec, adjust: Callable | None = None, progress: Callable[[str], None] | None = None
) -> CompareResult:
    """Run each control method of ``spec`` on the drive file's drives
    ([`pmsmjax.jobs.control_comparison.compare_controllers`][pmsmjax.jobs.control_comparison.compare_controllers]).
    ``adjust``: ``(drive, name) -> drive`` applied to each drive before anything runs (tuned gains, say);
    ``progress``: takes a line per run."""
    from pmsmjax.jobs.control_comparison import compare_controllers

    settings = _settings(spec, equal_switching_hz=spec.equal_switching_hz)
    t0 = time.perf_counter()
    result = compare_controllers(
        list(spec.names),
        None,
        settings,
        progress=progress,
        adjust=adjust,
        machine=spec.machine,
        spec=spec.drive,
    )
    report = {"settings": result["settings"], "controllers": result["controllers"]}
    report["settings"]["machine"] = spec.machine
    report["settings"]["gains"] = spec.gains
    report["drive_file"] = spec.drive.summary()
    report["wall_time_s"] = time.perf_counter() - t0
    return CompareResult(report=report, comparison=result, warnings=_warnings(result))


def compare_observers(spec: CompareSpec, progress: Callable[[str], None] | None = None) -> CompareResult:
    """Run the book FOC drive sensorless with each observer of ``spec`` through its scenario
    ([`pmsmjax.jobs.estimator_comparison.compare_estimators`][pmsmjax.jobs.estimator_comparison.compare_estimators]),
    the drive file's motor in the observers' design rules. On a drive file with a flux map the file's own
    drive runs instead, each observer reading the map (``spec.observer_model``), through the file's
    scenario, and the low-speed sweep is the book's scaled to the drive
    ([`pmsmjax.jobs.estimator_comparison.LowSpeedSweep.for_drive`][pmsmjax.jobs.estimator_comparison.LowSpeedSweep.for_drive]).
    ``progress``: takes the table's header, then a row per observer."""
    import numpy as np

    from pmsmjax.analysis.observer_errors import angle_error, angle_error_modulo_pi
    from pmsmjax.assemble import spec_motor
    from pmsmjax.jobs.estimator_comparison import (
        ESTIMATOR_COLUMNS,
        LowSpeedSweep,
        compare_estimators,
        estimator_table,
    )
    from pmsmjax.units import rad_s_to_rpm

    settings = _settings(spec)
    motor = spec_motor(spec.drive)
    on_map = spec.drive.flux_map is not None
    # the map's plant needs the file's own drive; a file without a map keeps the book drive on its motor
    own = dict(spec=spec.drive, observer_model=spec.observer_model or "map") if on_map else {}
    book_sweep = LowSpeedSweep(load_nm=spec.load_nm)
    sweep = LowSpeedSweep.for_drive(spec.drive, spec.load_nm) if on_map else book_sweep
    t0 = time.perf_counter()
    if progress:
        progress("  ".join(h for h, _, _ in ESTIMATOR_COLUMNS))
    result = compare_estimators(
        list(spec.names),
        motor,
        settings,
        sweep,
        progress=progress,
        scenario=spec.scenario,
        initial_angle_deg=spec.initial_angle_deg,
        **own,
    )
    report = {"settings": result["settings"], "estimators": result["controllers"]}
    report["drive_file"] = spec.drive.summary()
    report["wall_time_s"] = time.perf_counter() - t0
    first = next(iter(result["traces"].values()))
    errors = {}
    for name, trace in result["traces"].items():
        modulo_pi = result["controllers"][name]["angle_modulo"] == "pi"  # injection without polarity
        error = angle_error_modulo_pi if modulo_pi else angle_error
        theta_est, theta = (np.asarray(a, np.float64) for a in (trace.theta_e_est, trace.theta_e))
        errors[f"{name} (mod pi)" if modulo_pi else name] = np.degrees(error(theta_est, theta))
    angle_errors = {
        "t": np.asarray(first.t),
        "speed_rpm": rad_s_to_rpm(np.asarray(first.omega_m)),
        "errors": errors,
    }
    # the fixed scenarios' load steps (pmsmjax.jobs.estimator_comparison.ESTIMATOR_SCENARIOS)
    load_time = None if spec.scenario == "book" else 0.15 if spec.scenario == "reversal" else 0.1
    return CompareResult(
        report=report,
        comparison=result,
        warnings=_warnings(result),
        table=estimator_table(result) + "\n",
        angle_errors=angle_errors,
        load_time_s=load_time,
    )
