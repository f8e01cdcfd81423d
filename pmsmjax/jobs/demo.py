"""``pmsmjax demo``: one drive's scenario under one control method, from a
[`DemoSpec`][pmsmjax.jobs.demo.DemoSpec] (what the command's flags ask for) to a
[`DemoResult`][pmsmjax.jobs.demo.DemoResult] (the trace, summary.json's content, the console's lines and what
the figures need).

Importing this module loads no JAX: [`check_reference_speed`][pmsmjax.jobs.demo.check_reference_speed] belongs
to the command's checks before any work; [`build`][pmsmjax.jobs.demo.build] (the drive and the scenario, every
refusal before the first compile) and [`run`][pmsmjax.jobs.demo.run] (the simulation and its summary) import
the engine when called.
"""

import dataclasses
import time
from collections.abc import Callable, Mapping

from pmsmjax.spec import registry
from pmsmjax.spec.schema import MAX_RUN_PERIODS
from pmsmjax.spec.validation import ParameterError, plain

__all__ = [
    "MAX_LOAD_FACTOR",
    "DEFINITIONS",
    "MAX_SPEED_FACTOR",
    "DemoResult",
    "DemoSpec",
    "build",
    "check_reference_speed",
    "check_load",
    "dead_time_entry",
    "flux_map_entry",
    "run",
    "z_current_peak",
]

#: A reference beyond this many times the top speed the drive could reach at no load is refused: the run
#: would only show saturation (up to it, the run is made and its saturation reported).
MAX_SPEED_FACTOR = 3.0
#: A load beyond this many times the torque the current limit gives is refused: the speed would only run
#: away (up to it, the run is made and the shortfall reported).
MAX_LOAD_FACTOR = 10.0

#: What summary.json's less obvious figures mean.
DEFINITIONS = {
    "steady_state_error_rpm": "mean of reference - speed over the last 10 % of the samples before the load "
    "step, r/min",
    "final_error_rpm": "mean of reference - speed over the last n samples of the run, n = a tenth of the "
    "samples before the load step (the same window length as steady_state_error_rpm), r/min",
    "rise_time_s": "10 % to 90 % of the step, s (null: not reached)",
    "settling_time_s": "last entry into the 2 % band around the reference, s (null: not settled)",
    "speed_dip_rpm": "largest drop below the reference after the load step, r/min",
    "recovery_time_s": "time from the load step until the speed stays within recovery_band_rpm, s",
    "itae_rad_s": "integral of t |reference - speed| over the run, speed in rad/s (rad s)",
    "operating_point": "voltage_limited_share / current_limited_share: share of the control periods at the "
    "voltage or current limit; segments: whether the mean speed over the last 10 % before the load step and "
    "of the run is within the tolerance of the reference; flags: each shortfall with cause and remedy",
}


@dataclasses.dataclass(frozen=True)
class DemoSpec:
    """What one demo run is asked for (the command's flags, checked, with the drive file's scenario
    filling what the user left unset).

    - `drive`: the drive file ([`DriveSpec`][pmsmjax.spec.drive_spec.DriveSpec]); `motor`: ``--motor`` as
      given; `name`: the drive as the console and the figures name it.
    - `machine`: ``three-phase``, ``six-phase`` or ``five-phase``; `control`: a control method of the
      registry on it; `estimator`: a sensorless observer (three-phase FOC only) or None for the file's
      sensor; `observer_model`: ``map`` or ``constant`` with a flux map (None: ``map``).
    - `speed_rpm`, `load_nm`, `load_time_s`, `duration_s`: the scenario (speed step at 0, load step).
    - `options`: the preset options the flags set ([`pmsmjax.assemble.assemble`][pmsmjax.assemble.assemble]);
      with `field_weakening` the MTPA and voltage-feedback field weakening is added, its voltage loop a third
      of `current_bandwidth` (rad/s; None: the drive file's current loop).
    - `flags`: the flags the user set, by name, as summary.json repeats them; `operating_flags`: the
      command's names of the knobs the operating-point remedies name
      ([`pmsmjax.analysis.operating_point.run_flags`][pmsmjax.analysis.operating_point.run_flags]).
    - `frame`, `pwm`, `bridge`: the model frame and the multi-phase modulator and bridge asked for (None:
      the defaults), as summary.json reports them; `gains`: the gains file, or None.
    - `decimate`: record every n-th control period.
    - `margins`: also linearise the drive at the scenario's final speed and load and report both loops'
      margins ([`pmsmjax.analysis.margins.drive_margins`][pmsmjax.analysis.margins.drive_margins]).
    """

    drive: object
    motor: str
    name: str
    machine: str
    control: str
    speed_rpm: float
    load_nm: float
    load_time_s: float
    duration_s: float
    options: Mapping[str, object] = dataclasses.field(default_factory=dict)
    flags: Mapping[str, object] = dataclasses.field(default_factory=dict)
    operating_flags: Mapping[str, str] = dataclasses.field(default_factory=dict)
    estimator: str | None = None
    observer_model: str | None = None
    field_weakening: bool = False
    current_bandwidth: float | None = None
    frame: str | None = None
    pwm: str | None = None
    bridge: str | None = None
    gains: str | None = None
    decimate: int = 1
    margins: bool = False

    @property
    def multiphase(self) -> bool:
        """Whether the machine is the six- or five-phase one."""
        return self.machine != "three-phase"


@dataclasses.dataclass(frozen=True)
class DemoResult:
    """What a demo run gives its writer.

    - `trace`: the run's [`Trace`][pmsmjax.trace.Trace] (NumPy arrays, every `decimate`-th period).
    - `summary`: summary.json's content.
    - `console`: the lines the console reports, in order (the drive, the step, the load step, each
      operating-point flag, a flux-map warning, the timing).
    - `current_limit_a`, `voltage_limit_v`: the limits the figures draw, A and V (peak).
    - `layout`: the multi-phase winding's [`PhaseLayout`][pmsmjax.frames.multiphase.PhaseLayout] (its
      second-plane currents' figure), None for three phases.
    """

    trace: object
    summary: dict
    console: tuple[str, ...]
    current_limit_a: float
    voltage_limit_v: float
    layout: object | None = None


def trace_column_count(machine: str) -> int:
    """Columns of the trace a run of ``machine`` (``"three-phase"``, ``"six-phase"``, ``"five-phase"``)
    writes, for its memory plan."""
    from pmsmjax.trace import COLUMN_UNITS, FIVE_PHASE_COLUMN_UNITS, SIX_PHASE_COLUMN_UNITS

    extra = {"six-phase": SIX_PHASE_COLUMN_UNITS, "five-phase": FIVE_PHASE_COLUMN_UNITS}.get(machine, {})
    return len(COLUMN_UNITS) + len(extra)


def check_load(drive, load_nm: float, load_name: str = "--load-nm") -> None:
    """Refuse a load beyond [`MAX_LOAD_FACTOR`][pmsmjax.jobs.demo.MAX_LOAD_FACTOR] times the torque
    ``1.5 p psi_f I_max`` of the three-phase drive file ``drive`` at its current limit (pure Python);
    `load_name`: the flag or file field the value came from."""
    motor = drive.motor
    torque = 1.5 * motor["pole_pairs"] * motor["psi_f"] * drive.current_limit_a
    if abs(load_nm) > MAX_LOAD_FACTOR * torque:
        raise ParameterError(
            f"{load_name} {plain(load_nm)}: this drive gives about {torque:.3g} N m at its "
            f"{plain(drive.current_limit_a)} A current limit; a load beyond {MAX_LOAD_FACTOR:g}x that would "
            f"only make the speed run away: give a load in N m, at most {MAX_LOAD_FACTOR * torque:.3g} in "
            "magnitude, or raise the current limit (--current-limit)."
        )


def check_reference_speed(
    drive, speed_rpm: float, field_weakening: bool, u_dc_flag: str, speed_name: str = "--speed-rpm"
) -> None:
    """Refuse a speed reference beyond [`MAX_SPEED_FACTOR`][pmsmjax.jobs.demo.MAX_SPEED_FACTOR] times the
    no-load top speed of the three-phase drive file ``drive`` (with i_d = 0, or with field weakening: the
    closed form of
    [`pmsmjax.spec.steady_state.no_load_field_weakening_top_speed_rpm`][pmsmjax.spec.steady_state.no_load_field_weakening_top_speed_rpm]);
    pure Python. ``u_dc_flag``: the DC-link knob the fix names; `speed_name`: the flag or file field the
    value came from."""
    from pmsmjax.spec.steady_state import no_load_field_weakening_top_speed_rpm, top_speed_rpm

    motor, u_dc, u_limit, limit = drive.motor, drive.u_dc_v, drive.voltage_limit_v, drive.current_limit_a
    if field_weakening:
        top = no_load_field_weakening_top_speed_rpm(motor, u_limit, limit)
    else:
        top = abs(top_speed_rpm(motor, u_limit, 0.0))
    if abs(speed_rpm) > MAX_SPEED_FACTOR * top:
        raise ParameterError(
            f"{speed_name} {plain(speed_rpm)}: this drive cannot turn faster than about {top:.0f} r/min "
            f"(no load, U_dc = {plain(u_dc)} V"
            + (", field weakening" if field_weakening else ", i_d = 0")
            + f"); a reference beyond {MAX_SPEED_FACTOR:g}x that would only show saturation: give at most "
            f"{MAX_SPEED_FACTOR * top:.0f} r/min"
            + ("" if field_weakening else ", add --field-weakening")
            + f", or raise the DC link ({u_dc_flag})."
        )


def build(spec: DemoSpec, adjust: Callable | None = None):
    """The drive and the scenario of ``spec``, checked: a duration that is not a whole number of control
    periods, a ``decimate`` that does not divide them, or what
    [`pmsmjax.simulate.check_simulation`][pmsmjax.simulate.check_simulation] refuses is a
    [`ParameterError`][pmsmjax.spec.validation.ParameterError] before anything compiles. ``adjust``:
    ``(drive, control) -> drive`` applied once the drive is built (tuned gains, say; after the observer is in,
    so gains may name ``estimator.*``). Returns ``(drive, scenario)``."""
    from pmsmjax.assemble import assemble, spec_scenario
    from pmsmjax.simulate import check_simulation

    options = dict(spec.options)
    if spec.field_weakening:
        from pmsmjax.presets import field_weakening_block

        bandwidth = spec.current_bandwidth or spec.drive.control["current_bandwidth_rad_s"]
        options["d_axis"] = field_weakening_block(bandwidth)
    drive = assemble(
        spec.drive,
        spec.control,
        machine=spec.machine,
        options=options,
        estimator=spec.estimator,  # three-phase only; the drive file's I/f start
        observer_model=spec.observer_model or "map",
    )
    if adjust is not None:
        drive = adjust(drive, spec.control)
    scenario = spec_scenario(spec.drive, spec.speed_rpm, spec.load_nm, spec.load_time_s, spec.duration_s)
    n = spec.duration_s / drive.Ts
    if n > MAX_RUN_PERIODS:
        raise ParameterError(
            f"--duration-s {plain(spec.duration_s)} is {n:.3g} control periods, more than the "
            f"{MAX_RUN_PERIODS:.0e} a run may have: give at most {plain(MAX_RUN_PERIODS * drive.Ts)} s."
        )
    if abs(n - round(n)) > 1e-6 * max(n, 1.0):
        raise ParameterError(
            f"--duration-s {plain(spec.duration_s)} is not a whole number of {plain(drive.Ts * 1e3)} ms "
            f"control periods: give e.g. {plain(round(n) * drive.Ts)} s."
        )
    if round(n) % spec.decimate:
        raise ParameterError(
            f"--decimate {spec.decimate} does not divide the {round(n)} control periods of the run: give "
            "a divisor of it (1, 2, 5, 10, ...)."
        )
    check_simulation(drive, scenario, spec.decimate)
    return drive, scenario


def run(spec: DemoSpec, drive, scenario) -> DemoResult:
    """Simulate ``drive`` through ``scenario`` (from [`build`][pmsmjax.jobs.demo.build]) twice, the second
    call timed without compiling; judge the run
    ([`pmsmjax.analysis.speed_step_summary.speed_step_summary`][pmsmjax.analysis.speed_step_summary.speed_step_summary],
    [`pmsmjax.analysis.operating_point.run_flags`][pmsmjax.analysis.operating_point.run_flags]) and describe
    it."""
    import jax
    import numpy as np

    from pmsmjax.analysis.operating_point import run_flags
    from pmsmjax.analysis.speed_step_summary import speed_step_summary
    from pmsmjax.simulate import simulate
    from pmsmjax.trace import COLUMN_UNITS

    speed_m = spec.speed_rpm * np.pi / 30.0
    if spec.margins:  # refused before the simulation compiles
        from pmsmjax.analysis.loop_linearisation import check_linearisable

        check_linearisable(drive, speed_m, spec.load_nm, where="--speed-rpm, --load-nm")
    t0 = time.perf_counter()
    trace = jax.block_until_ready(simulate(drive, scenario, decimate=spec.decimate))
    first_call_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    trace = jax.block_until_ready(simulate(drive, scenario, decimate=spec.decimate))
    run_s = time.perf_counter() - t0
    trace = trace.to_numpy()

    load_time = spec.load_time_s if 0 < spec.load_time_s < spec.duration_s else None
    current_limit = float(np.asarray(drive.controller.current_limit))
    operating = run_flags(
        trace, drive, load_time_s=load_time, field_weakening=spec.field_weakening, flags=spec.operating_flags
    )
    with np.errstate(divide="ignore", invalid="ignore"):  # a step to 0 r/min has no overshoot: null
        step_metrics = speed_step_summary(trace, load_time_s=load_time, current_limit_a=current_limit)
    summary = {
        "scenario": {
            "speed_rpm": spec.speed_rpm,
            "load_nm": spec.load_nm,
            "load_time_s": spec.load_time_s,
            "duration_s": spec.duration_s,
        },
        "drive": {
            "machine": spec.machine,
            "motor": spec.motor,
            "control": spec.control,
            "estimator": spec.estimator
            or ("encoder" if spec.drive.sensor["kind"] == "encoder" else "exact sensor"),
            "observer_model": (spec.observer_model or "map")
            if spec.estimator and "flux_map" in spec.drive.motor
            else None,
            "frame": spec.frame or "dq",
            "Ts_s": drive.Ts,
            "n_substeps": drive.n_substeps,
            "computation_delay": drive.computation_delay,
            "options": dict(spec.flags),
            "gains": spec.gains,
            "current_limit_a": current_limit,
            "u_dc_v": float(np.asarray(drive.bridge.u_dc)),
            "bridge_dead_time": dead_time_entry(spec.drive, drive),
            "sensors": sensors_entry(drive),
        },
        "drive_file": spec.drive.summary(),
        "metrics": step_metrics,
        "operating_point": operating,
        **flux_map_entry(drive, trace),
        "definitions": DEFINITIONS,
        "trace_columns": COLUMN_UNITS,
        "timing": {"compile_s": max(first_call_s - run_s, 0.0), "run_s": run_s},
    }
    layout = None
    if spec.multiphase:
        from pmsmjax.trace import FIVE_PHASE_COLUMN_UNITS, SIX_PHASE_COLUMN_UNITS

        five = spec.machine == "five-phase"
        layout = drive.machine.layout
        extra = FIVE_PHASE_COLUMN_UNITS if five else SIX_PHASE_COLUMN_UNITS
        summary["trace_columns"] = {**COLUMN_UNITS, **extra}
        summary["drive"]["pwm"] = spec.pwm or registry.default("modulator", spec.machine)
        summary["drive"]["bridge"] = spec.bridge or "averaged"
        peak = "xy_current_peak_a" if five else "z_current_peak_a"
        summary["metrics"][peak] = z_current_peak(trace, layout)
    if drive.thermal is not None:
        from pmsmjax.trace import THERMAL_COLUMN_UNITS

        summary["drive"]["thermal"] = thermal_entry(drive, trace)
        summary["trace_columns"] = {**summary["trace_columns"], **THERMAL_COLUMN_UNITS}
    if trace.load_speed is not None:  # a compliant shaft: the load's own speed
        from pmsmjax.trace import SHAFT_COLUMN_UNITS

        summary["trace_columns"] = {**summary["trace_columns"], **SHAFT_COLUMN_UNITS}
    if spec.margins:
        from pmsmjax.analysis.margins import drive_margins

        t0 = time.perf_counter()
        summary["loop_margins"] = drive_margins(drive, speed_m, spec.load_nm, "--speed-rpm, --load-nm")
        summary["timing"]["margins_s"] = time.perf_counter() - t0
    if trace.cogging_torque is not None:
        from pmsmjax.trace import COGGING_COLUMN_UNITS

        summary["trace_columns"] = {**summary["trace_columns"], **COGGING_COLUMN_UNITS}
    return DemoResult(
        trace=trace,
        summary=summary,
        console=_console(spec, summary, drive.Ts),
        current_limit_a=current_limit,
        voltage_limit_v=float(np.asarray(drive.voltage_limit())),
        layout=layout,
    )


def _console(spec: DemoSpec, summary: dict, Ts: float) -> tuple[str, ...]:
    """The console's report of a finished run ([`DemoResult.console`][pmsmjax.jobs.demo.DemoResult]); a
    figure the run does not define (an overshoot of a step to 0 r/min, summary.json's null) reads n/a."""
    m, limit = summary["metrics"], summary["drive"]["current_limit_a"]
    m = {k: _Undefined() if v is None else v for k, v in m.items()}
    lines = [
        f"{spec.name} drive ({spec.machine}, U_dc {plain(summary['drive']['u_dc_v'])} V, current limit "
        f"{plain(limit)} A, {plain(1e-3 / Ts)} kHz), {spec.control} control",
        f"final speed {m['final_speed_rpm']:.1f} r/min (ref {m['reference_speed_rpm']:.0f}), "
        f"rise {_fmt(m['rise_time_s'], 1e3)} ms, overshoot {m['overshoot_pct']:.2f} %, "
        f"settling {_fmt(m['settling_time_s'], 1e3)} ms",
    ]
    if "speed_dip_rpm" in m:
        lines.append(
            f"load step: dip {m['speed_dip_rpm']:.1f} r/min, recovery {_fmt(m['recovery_time_s'], 1e3)} ms; "
            f"peak current {m['peak_phase_current_a']:.2f} A (limit {m['current_limit_a']:.1f} A)"
        )
    for f in summary["operating_point"]["flags"]:
        lines.append(f"WARNING {f['flag']}: {f['cause']}; remedy: {f['remedy']}.")
    if summary.get("flux_map", {}).get("warning"):
        lines.append(f"WARNING flux_map: {summary['flux_map']['warning']}")
    if "thermal" in summary["drive"]:
        t = summary["drive"]["thermal"]
        lines.append(
            f"warm motor: winding {t['winding_start_c']:.1f} -> {t['winding_end_c']:.1f} degC "
            f"(ambient {plain(t['ambient_c'])} degC): R {t['r_change_pct']:+.1f} %, psi_f "
            f"{t['psi_f_change_pct']:+.1f} % at the end, against the data at {plain(t['reference_c'])} degC"
        )
    if "loop_margins" in summary:
        from pmsmjax.analysis.margins import margins_line

        lines.append(margins_line(summary["loop_margins"]))
    timing = summary["timing"]
    lines.append(f"compile {timing['compile_s']:.2f} s, run {timing['run_s'] * 1e3:.1f} ms")
    return tuple(lines)


def sensors_entry(drive) -> dict:
    """What the controller's sensors are, for summary.json: the phase-current sensors (``"ideal"``, or the
    sensed phases with their offsets A, gains and ADC step A) and, for an encoder, its lines, latency (s)
    and mounting offset (electrical rad)."""
    import numpy as np

    from pmsmjax.estimators.position_sensors import Encoder

    def values(x):  # float32 leaves as the numbers the file gave (7 significant digits)
        return [float(f"{v:.7g}") for v in np.atleast_1d(np.asarray(x, float))]

    cs = drive.current_sensor
    entry = {"current": "ideal"}
    if not cs.is_ideal:
        entry["current"] = {
            "sensed_phases": "abc"[: cs.n_sensors],
            "reconstructed": "c = -a - b" if cs.n_sensors == 2 else None,
            "offset_a": values(cs.offset_a),
            "gain": values(cs.gain),
            "lsb_a": None if cs.lsb_a is None else values(cs.lsb_a)[0],
        }
    if isinstance(drive.estimator, Encoder):
        e = drive.estimator
        entry["encoder"] = {
            "lines": e.lines,
            "delay_s": float(np.asarray(e.delay_s)),
            "offset_rad": 0.0 if e.offset_rad is None else values(e.offset_rad)[0],
        }
    return entry


def thermal_entry(drive, trace) -> dict:
    """summary.json's account of a warm motor (a drive with a thermal network): the model, its values, the
    winding temperature at the start and end of the run (degC), and ``R``, ``psi_f`` at the end against
    their reference values (%)."""
    import numpy as np

    from pmsmjax.units import kelvin_to_celsius

    t = drive.thermal
    start, end = (float(kelvin_to_celsius(np.asarray(trace.winding_temperature)[i])) for i in (0, -1))
    k_r, k_psi = (float(np.asarray(k)) for k in t.factors(np.asarray(trace.winding_temperature)[-1]))
    value = lambda x: float(np.asarray(x))
    return {
        "model": "one-node winding network C_th dT/dt = 1.5 R(T) |i_dq|^2 - (T - T_amb) / R_th; "
        "R(T) = R (1 + alpha (T - T_ref)), psi_f(T) = psi_f (1 + beta (T - T_ref))",
        "r_th_k_per_w": value(t.r_th),
        "c_th_j_per_k": value(t.c_th),
        "time_constant_s": value(t.time_constant_s),
        "ambient_c": value(kelvin_to_celsius(t.ambient_k)),
        "reference_c": value(kelvin_to_celsius(t.reference_k)),
        "r_temp_coeff_per_k": value(t.r_temp_coeff),
        "psi_f_temp_coeff_per_k": value(t.psi_f_temp_coeff),
        "winding_start_c": start,
        "winding_end_c": end,
        "r_change_pct": 100.0 * (k_r - 1.0),
        "psi_f_change_pct": 100.0 * (k_psi - 1.0),
    }


def dead_time_entry(spec, drive) -> dict:
    """summary.json's account of the drive file's dead time and device drop: what the bridge that ran
    models (the averaged bridge's period-average error, or the switching bridge's dead windows) and
    whether the controller compensates them."""
    t_d, drop = spec.inverter["dead_time_s"], spec.inverter.get("device_drop_v", 0.0)
    from pmsmjax.controllers.foc import FOC
    from pmsmjax.inverters.averaged import AveragedBridge
    from pmsmjax.inverters.multiphase_bridges import MultiPhaseSwitchingBridge

    bridge = drive.bridge
    if isinstance(bridge, AveragedBridge):
        error = bridge.voltage_error
        modelled = error is not None and float(error.dead_time) > 0.0
        how = "period-averaged by the averaged bridge"
    else:
        modelled = isinstance(bridge, MultiPhaseSwitchingBridge) and bridge.resolve_dead_time
        how = "resolved edge by edge by the switching bridge"
    compensation = drive.controller.dead_time_compensation if isinstance(drive.controller, FOC) else None
    entry = {
        "dead_time_s": t_d,
        "device_drop_v": drop,
        "modelled": bool(modelled and t_d > 0.0),
        "compensated": compensation is not None,
    }
    if t_d > 0.0 and modelled:
        entry["how"] = how
    if t_d > 0.0 and not modelled:
        entry["note"] = (
            f"[inverter] dead_time_s = {t_d:g} s is not modelled by this bridge ({type(bridge).__name__}): "
            "the three-phase averaged bridge and the switching bridges model it (six- and five-phase: "
            "--bridge switching)"
        )
    return entry


def flux_map_entry(drive, trace) -> dict:
    """``{"flux_map": ...}`` for summary.json when the plant is a flux map: how far the run's currents went
    outside the map's grid ([`pmsmjax.machines.flux_map.excursion`][pmsmjax.machines.flux_map.excursion]);
    ``{}`` otherwise."""
    from pmsmjax.machines.pmsm_flux_map import PMSMFluxMapdq

    if not isinstance(drive.machine, PMSMFluxMapdq):
        return {}
    return {"flux_map": drive.machine.flux_map.excursion(trace.i_dq)}


def z_current_peak(trace, layout=None) -> float:
    """Largest |z1-z2| current (A) of a six-phase trace (|x-y| of a five-phase one: ``layout``)."""
    import numpy as np

    from pmsmjax.frames.multiphase import SIX_PHASE, vsd

    i_z = np.asarray(vsd(trace.i_abc, SIX_PHASE if layout is None else layout))[:, 2:4]
    return float(np.max(np.hypot(i_z[:, 0], i_z[:, 1])))


def _fmt(x, scale):
    return "n/a" if x is None or isinstance(x, _Undefined) else f"{x * scale:.1f}"


class _Undefined:
    """A figure the run does not define, formatted as ``n/a`` whatever the format asks."""

    def __format__(self, spec: str) -> str:
        return "n/a"
