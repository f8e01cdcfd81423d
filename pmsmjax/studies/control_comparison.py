"""Controllers side by side on the book scenario (the book, ch. 3; later chapters add their methods).

Every controller drives the same motor through the same scenario (speed step from rest, load step). The
step and load figures come from
[`pmsmjax.analysis.speed_step_summary.speed_step_summary`][pmsmjax.analysis.speed_step_summary.speed_step_summary];
the ripple figures from the last ``window_cycles`` whole electrical periods of the run (steady state under
load):

- current THD of phase a up to ``thd_max_frequency_hz``
  ([`pmsmjax.analysis.spectra`][pmsmjax.analysis.spectra]), from uniform
samples
  of the trajectory *inside* each period
  ([`pmsmjax.analysis.within_period.dense_window`][pmsmjax.analysis.within_period.dense_window]);
- torque ripple: RMS and peak-to-peak of the electromagnetic torque about its window mean, same samples;
- mean switching frequency of the legs
  ([`pmsmjax.analysis.metrics.switching_frequency_hz`][pmsmjax.analysis.metrics.switching_frequency_hz]);
- stator flux-magnitude ripple: RMS and peak-to-peak of the plant's true ``|psi|`` about its window mean
  (``psi_dq = [L_d i_d + psi_f, L_q i_q]`` of the same samples), for every controller whether or not it
  estimates the flux (the flux is what direct torque control regulates; under FOC it follows the
  currents).

At equal switching frequency (``equal_switching_hz``): each controller with bands (table DTC, hysteresis
current control; [`pmsmjax.studies.equal_switching`][pmsmjax.studies.equal_switching]) is run a second time,
as ``"NAME@F kHz"``, with its bands scaled so that its mean switching frequency over the same window meets the
given frequency (by default the
PWM frequency ``1/Ts`` of the voltage-commanding controllers compared).

Voltage-commanding controllers run on the switching-resolved bridge by default (``bridge="switching"``):
with the averaged bridge the PWM ripple is not in the model, and its THD and torque ripple would read
near zero next to the hysteresis controller's, which switches in the model itself.
"""

import dataclasses
import math
import re

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from pmsmjax import presets
from pmsmjax.analysis import metrics
from pmsmjax.analysis.observer_errors import observer_errors, speed_held
from pmsmjax.analysis.operating_point import run_flags
from pmsmjax.analysis.spectra import sampled_spectrum, thd
from pmsmjax.analysis.speed_step_summary import speed_step_summary
from pmsmjax.analysis.within_period import dense_window
from pmsmjax.checks.validation import ParameterError
from pmsmjax.drive import Drive
from pmsmjax.frames.three_phase import inverse_park
from pmsmjax.inverters.switching import SwitchingBridge
from pmsmjax.machines.motor import PMSMParameters
from pmsmjax.presets.control_methods import CONTROLS, control_drive
from pmsmjax.presets.five_phase import FIVE_PHASE_CONTROLS, five_phase_drive
from pmsmjax.presets.six_phase import SIX_PHASE_CONTROLS, six_phase_drive
from pmsmjax.simulate import check_simulation, simulate
from pmsmjax.studies.equal_switching import BAND_LEAVES, match_switching_frequency
from pmsmjax.units import rad_s_to_rpm

SUMMARY_KEYS = {
    "rise_time_s": "rise_time_s",
    "overshoot_pct": "overshoot_pct",
    "dip_rpm": "speed_dip_rpm",
    "recovery_time_s": "recovery_time_s",
    "itae": "itae_rad_s",
    "final_speed_rpm": "final_speed_rpm",
}


@dataclasses.dataclass(frozen=True)
class ControllerCompareSettings:
    """The scenario and the analysis.

    - `speed_rpm`, `load_nm`, `load_time_s`, `duration_s`: the book scenario (speed step at 0, load step).
    - `window_cycles`: whole electrical periods at the end of the run analysed for ripple and THD.
    - `sample_rate_hz`: intra-period sampling rate of the ripple analysis (at least one sample a period).
    - `thd_max_frequency_hz`: THD includes components up to this frequency (4 x the book's 10 kHz).
    - `bridge`: ``"switching"`` (segment-exact) or ``"averaged"`` for voltage-commanding controllers.
    - `equal_switching_hz`: also run each controller with bands at this mean switching frequency, Hz
      (``0``: the PWM frequency of the voltage-commanding controllers; ``None``: not).
    """

    speed_rpm: float = 1000.0
    load_nm: float = 10.0
    load_time_s: float = 0.2
    duration_s: float = 0.4
    window_cycles: int = 2
    sample_rate_hz: float = 320e3
    thd_max_frequency_hz: float = 40e3
    bridge: str = "switching"
    equal_switching_hz: float | None = None

    def check(self) -> None:
        """Raise [`ParameterError`][pmsmjax.checks.validation.ParameterError] naming the first inconsistent
        setting (unknown bridge, no speed, load step outside the run, too low a sampling rate for the THD)."""
        if self.bridge not in ("switching", "averaged"):
            raise ParameterError(f"bridge must be 'switching' or 'averaged', got {self.bridge!r}.")
        if self.speed_rpm <= 0:
            raise ParameterError(f"speed_rpm must be > 0 for a ripple window, got {self.speed_rpm}.")
        if not 0 < self.load_time_s < self.duration_s:
            raise ParameterError(
                f"load_time_s = {self.load_time_s} s must lie inside the run (0, {self.duration_s}) s."
            )
        if self.sample_rate_hz < 2.5 * self.thd_max_frequency_hz:
            raise ParameterError(
                f"sample_rate_hz = {self.sample_rate_hz:g} must exceed 2.5 x thd_max_frequency_hz "
                f"({self.thd_max_frequency_hz:g} Hz) so the spectrum reaches it."
            )
        if self.equal_switching_hz is not None and not self.equal_switching_hz >= 0:
            raise ParameterError(
                f"equal_switching_hz must be a frequency > 0 Hz, 0 (the PWM frequency of the compared "
                f"voltage-commanding controls) or None, got {self.equal_switching_hz!r}."
            )


#: Machines ``compare --control`` takes besides the three-phase one: name -> (drive function, its control
#: registry), both from the multi-phase presets (book chapters 7-10).
MULTIPHASE_PRESETS = {
    "six-phase": (six_phase_drive, SIX_PHASE_CONTROLS),
    "five-phase": (five_phase_drive, FIVE_PHASE_CONTROLS),
}


def machine_controls(machine: str) -> tuple[str, ...]:
    """The control names ``compare`` takes on ``machine`` (``three-phase``, ``six-phase``, ``five-phase``)."""
    if machine == "three-phase":
        return tuple(CONTROLS)
    return tuple(MULTIPHASE_PRESETS[machine][1])


def compared_drive(
    name: str, motor=None, bridge: str = "averaged", machine: str = "three-phase", spec=None
) -> Drive:
    """The drive of control ``name`` for ``motor`` on ``bridge``:
    [`pmsmjax.presets.control_methods.CONTROLS`][pmsmjax.presets.control_methods.CONTROLS] for the
    three-phase machine, the six- or five-phase presets' schemes (``vsd``, ...) for ``machine``; ``motor``
    is then a
    [`pmsmjax.machines.MultiPhaseParameters`][pmsmjax.machines.multiphase_motor.MultiPhaseParameters] (None:
    the preset's rewind of the book motor). With a drive file ``spec``
    ([`pmsmjax.io.drive_files.DriveSpec`][pmsmjax.io.drive_files.DriveSpec]) instead of ``motor``: its drive
    ([`pmsmjax.presets.user_drive.spec_drive`][pmsmjax.presets.user_drive.spec_drive]; a multi-phase switching
    bridge with the file's dead time)."""
    if spec is not None:
        from pmsmjax.presets.user_drive import spec_drive

        if machine != "three-phase":
            return spec_drive(spec, name, bridge=bridge)
        drive = spec_drive(spec, name)
    elif machine != "three-phase":
        preset = MULTIPHASE_PRESETS[machine][0]
        return preset(motor, control=name, bridge=bridge)
    else:
        drive = control_drive(name, motor)
    if bridge == "switching" and drive.controller.command_kind == "voltage":
        drive = eqx.tree_at(lambda d: d.bridge, drive, SwitchingBridge(drive.bridge.u_dc))
    return drive


def window_periods(drive: Drive, settings: ControllerCompareSettings) -> int:
    """Control periods in ``window_cycles`` electrical periods (must be whole)."""
    f1 = settings.speed_rpm / 60.0 * drive.machine.motor.pole_pairs
    periods = settings.window_cycles / (f1 * drive.Ts)
    if abs(periods - round(periods)) > 1e-6 * periods:
        raise ParameterError(
            f"{settings.window_cycles} electrical periods at {settings.speed_rpm} r/min are not a whole "
            f"number of control periods ({drive.Ts * 1e6:g} us): choose a speed whose electrical period is a "
            "multiple of Ts (1000 r/min with 4 pole pairs: 15 ms)."
        )
    return int(round(periods))


def run_control(name: str, drive: Drive, settings: ControllerCompareSettings, initial_state=None) -> dict:
    """Simulate one controller (from ``initial_state``, default at rest at angle 0); returns its figures,
    its trace and its ripple window (NumPy)."""
    scenario = _scenario(settings)
    check_simulation(drive, scenario)
    n_window = window_periods(drive, settings)
    trace = simulate(drive, scenario, initial_state=initial_state).to_numpy()  # figures in NumPy
    limit = float(drive.controller.current_limit)
    summary = speed_step_summary(trace, load_time_s=settings.load_time_s, current_limit_a=limit)

    window = jax.tree.map(lambda x: x[-n_window:], trace)
    per_period = max(1, math.ceil(settings.sample_rate_hz * drive.Ts))
    dense, _, _ = dense_window(drive, window, per_period)
    machine = drive.machine
    flat = jax.tree.map(lambda x: x.reshape((-1,) + x.shape[2:]), dense)
    i_abc = np.asarray(jax.vmap(machine.phase_currents)(flat))
    torque = np.asarray(jax.vmap(machine.electromagnetic_torque)(flat))
    psi_ab = np.asarray(jax.vmap(lambda st: stator_flux_ab(machine, st))(flat))
    flux = np.hypot(psi_ab[:, 0], psi_ab[:, 1])
    window_s = n_window * drive.Ts
    n_max = int(settings.thd_max_frequency_hz * window_s)
    spectrum = sampled_spectrum(i_abc[:, 0], window_s, settings.window_cycles, n_max)
    entry = {key: summary[src] for key, src in SUMMARY_KEYS.items()}
    entry["operating_point"] = run_flags(trace, drive, load_time_s=settings.load_time_s)
    entry.update(
        {
            "peak_current_a": float(
                max(metrics.peak_phase_current(i_abc), metrics.peak_phase_current(trace.i_abc))
            ),
            "current_thd_pct": 100.0 * float(thd(spectrum, settings.thd_max_frequency_hz)),
            "switching_frequency_hz": float(metrics.switching_frequency_hz(window.duties, drive.Ts)),
            "torque_ripple_nm": float(np.std(torque)),
            "torque_ripple_pp_nm": float(np.ptp(torque)),
            "mean_torque_nm": float(np.mean(torque)),
            "flux_ripple_wb": float(np.std(flux)),
            "flux_ripple_pp_wb": float(np.ptp(flux)),
            "mean_flux_wb": float(np.mean(flux)),
            "current_limit_a": limit,
            "control_period_s": drive.Ts,
            "command": drive.controller.command_kind,
            "bridge": type(drive.bridge).__name__,
        }
    )
    for leaf in BAND_LEAVES.get(type(drive.controller), ()):
        entry[leaf] = float(getattr(drive.controller, leaf))
    t_window = (np.arange(i_abc.shape[0]) + 1) * (drive.Ts / per_period)
    window = {"t": t_window, "i_abc": i_abc, "torque": torque, "psi_ab": psi_ab}
    return {"entry": entry, "trace": trace, "window": window}


def stator_flux_ab(machine, state) -> np.ndarray:
    """``(2,)`` the plant's stator flux linkage in alpha-beta, Wb: ``[L_d i_d + psi_f, L_q i_q]`` rotated by
    the rotor angle (three-phase machines in any frame)."""
    m = machine.motor
    i_dq = machine.currents_dq(state)
    return inverse_park(jnp.stack([m.L_d * i_dq[0] + m.psi_f, m.L_q * i_dq[1]]), state.theta_e)


def pwm_frequency_hz(drives: dict) -> float:
    """The PWM frequency ``1/Ts`` (Hz) shared by the voltage-commanding drives (``drives``: name -> Drive)."""
    freqs = {round(1.0 / d.Ts, 6) for d in drives.values() if d.controller.command_kind == "voltage"}
    if len(freqs) != 1:
        raise ParameterError(
            "equal switching frequency needs one PWM frequency to match: the voltage-commanding controls "
            f"compared have {sorted(freqs) or 'none'} Hz; give the frequency explicitly."
        )
    return freqs.pop()


def compare_controllers(
    names,
    motor: PMSMParameters | None = None,
    settings=ControllerCompareSettings(),
    progress=None,
    adjust=None,
    machine: str = "three-phase",
    spec=None,
) -> dict:
    """Run each named controller (keys of
    [`pmsmjax.presets.control_methods.CONTROLS`][pmsmjax.presets.control_methods.CONTROLS], or of the six- or
    five-phase schemes with ``machine``:
    [`machine_controls`][pmsmjax.studies.control_comparison.machine_controls]) on the book scenario.

    With ``settings.equal_switching_hz`` each controller with bands is also run with its bands matched
    to that mean switching frequency (``0``: the PWM frequency of the voltage-commanding controllers,
    [`pwm_frequency_hz`][pmsmjax.studies.control_comparison.pwm_frequency_hz]), under the name
    ``"NAME@F kHz"``; its entry adds ``band_factor`` and ``band_search_runs``.

    Returns ``{"settings", "controllers": name -> figures, "traces": name -> Trace, "windows": name ->
    {t, i_abc, torque, psi_ab}}``; `progress`: optional callable taking a line per controller; `adjust`:
    optional ``(drive, name) -> drive`` applied to each drive before anything runs (tuned gains, say);
    `spec`: a drive file ([`pmsmjax.io.drive_files.DriveSpec`][pmsmjax.io.drive_files.DriveSpec]) whose drives
    run instead of ``motor``'s presets
    ([`compared_drive`][pmsmjax.studies.control_comparison.compared_drive]).
    """
    settings.check()
    if machine != "three-phase" and machine not in MULTIPHASE_PRESETS:
        raise ParameterError(f"machine {machine!r}: choose three-phase, {', '.join(MULTIPHASE_PRESETS)}.")
    known = machine_controls(machine)
    unknown = [n for n in names if n not in known]
    if unknown:
        raise ParameterError(f"unknown {machine} controls {unknown}: choose from {', '.join(known)}.")
    if machine != "three-phase" and settings.equal_switching_hz is not None:
        raise ParameterError(
            "equal switching frequency matches hysteresis/DTC bands; the multi-phase schemes are all PWM: "
            "drop it."
        )
    drives = {name: compared_drive(name, motor, settings.bridge, machine, spec) for name in names}
    if adjust is not None:
        drives = {name: adjust(drive, name) for name, drive in drives.items()}
    for drive in drives.values():  # every check before the first compile
        window_periods(drive, settings)
    target = settings.equal_switching_hz
    if target == 0:
        target = pwm_frequency_hz(drives)
    result = {"settings": dataclasses.asdict(settings), "controllers": {}, "traces": {}, "windows": {}}
    if target is not None:
        result["settings"]["equal_switching_hz"] = target
    for name, drive in drives.items():
        _record(result, name, run_control(name, drive, settings), progress)
        if target is not None and type(drive.controller) in BAND_LEAVES:
            match = match_switching_frequency(
                drive, _scenario(settings), target, window_periods(drive, settings)
            )
            matched = f"{name}@{target / 1e3:g}kHz"
            run = run_control(matched, match["drive"], settings)
            run["entry"]["band_factor"] = match["factor"]
            run["entry"]["band_search_runs"] = len(match["runs"])
            _record(result, matched, run, progress)
    return result


def _scenario(settings: ControllerCompareSettings):
    return presets.book_scenario(
        settings.speed_rpm, settings.load_nm, settings.load_time_s, settings.duration_s
    )


def _record(result: dict, name: str, run: dict, progress) -> None:
    result["controllers"][name] = run["entry"]
    result["traces"][name] = run["trace"]
    result["windows"][name] = run["window"]
    if progress:
        e = run["entry"]
        progress(
            f"{name:12s} rise {1e3 * e['rise_time_s']:6.1f} ms  dip {e['dip_rpm']:6.1f} r/min  "
            f"THD {e['current_thd_pct']:5.2f} %  f_sw {1e-3 * e['switching_frequency_hz']:5.1f} kHz  "
            f"T ripple {e['torque_ripple_nm']:.3f} N m  flux ripple {1e3 * e['flux_ripple_wb']:.2f} mWb"
        )


# --- Chapter 5: observers side by side (``pmsmjax compare --estimator``) ---------------------------------

#: Speeds (r/min) of the low-speed sweep under load, highest first.
LOW_SPEED_SWEEP_RPM = (500.0, 300.0, 200.0, 150.0, 100.0, 70.0, 50.0, 30.0, 20.0, 10.0, 5.0, 2.0)


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


def observer_drive(
    name: str, motor: PMSMParameters | None = None, bridge: str = "averaged", startup: bool = True
) -> Drive:
    """The book FOC drive with observer ``name``
    ([`pmsmjax.estimators.OBSERVERS`][pmsmjax.estimators.catalogue.OBSERVERS], design-rule gains for
    ``motor``) and the I/f start from standstill, on ``bridge``."""
    drive = presets.sensorless_drive(name, motor, startup=startup)
    if bridge == "switching":
        drive = eqx.tree_at(lambda d: d.bridge, drive, SwitchingBridge(drive.bridge.u_dc))
    return drive


def low_speed_sweep(drive: Drive, sweep: LowSpeedSweep = LowSpeedSweep(), r_factor: float = 1.0) -> dict:
    """Run ``drive`` (its plant's R times ``r_factor``) through every speed of ``sweep`` (one batched
    simulation); returns ``{"runs": [{speed_rpm, held, ...}], "lowest_held_rpm"}``: the lowest swept
    speed such that it and every higher swept speed were held (None if the highest was not)."""
    from pmsmjax.scenarios import stack_scenarios

    if r_factor != 1.0:
        drive = eqx.tree_at(lambda d: d.machine.motor.R, drive, drive.machine.motor.R * r_factor)

    scenarios = [sweep.scenario(s) for s in sweep.speeds_rpm]
    check_simulation(drive, scenarios[0])
    batch = stack_scenarios(scenarios)
    traces = jax.block_until_ready(jax.vmap(simulate, in_axes=(None, 0))(drive, batch))
    runs, lowest = [], None
    for i, speed in enumerate(sweep.speeds_rpm):
        trace = jax.tree.map(lambda x, i=i: np.asarray(x[i]), traces)
        run = {"speed_rpm": float(speed), **speed_held(trace, drive.Ts, sweep.judge_from_s)}
        runs.append(run)
    for run in runs:  # highest first: stop at the first speed not held
        if not run["held"]:
            break
        lowest = run["speed_rpm"]
    return {"runs": runs, "lowest_held_rpm": lowest, "r_factor": r_factor}


#: The scenarios of ``compare --estimator`` (``scenario=`` of
#: [`compare_estimators`][pmsmjax.studies.control_comparison.compare_estimators]): name -> (description,
#: estimator families it suits). ``book``: `_scenario` of the settings; the others are fixed runs
#: ([`estimator_scenario`][pmsmjax.studies.control_comparison.estimator_scenario]) at low speed or through
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
    [`ESTIMATOR_SCENARIOS`][pmsmjax.studies.control_comparison.ESTIMATOR_SCENARIOS] (all but ``book``) with
    the load ``load_nm`` (N m; ``reversal`` keeps its 5 N m)."""
    from pmsmjax.scenarios import Profile, Scenario
    from pmsmjax.studies.hybrid_runs import hybrid_scenarios
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
    drive = eqx.tree_at(lambda d: d.machine, drive, saturated_machine(motor))
    if bridge == "switching":
        drive = eqx.tree_at(lambda d: d.bridge, drive, SwitchingBridge(drive.bridge.u_dc))
    return drive


def run_estimator_scenario(drive: Drive, scenario, initial_state) -> dict:
    """Simulate ``drive`` through a fixed scenario
    ([`estimator_scenario`][pmsmjax.studies.control_comparison.estimator_scenario]) from ``initial_state``;
    its figures (ITAE of the speed error, rad s; largest speed deviation from the reference, r/min, after
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
    settings=ControllerCompareSettings(),
    sweep: LowSpeedSweep | None = LowSpeedSweep(),
    progress=None,
    scenario: str = "book",
    initial_angle_deg: float | None = None,
) -> dict:
    """Run the book FOC drive sensorless with each named estimator through ``scenario``
    ([`ESTIMATOR_SCENARIOS`][pmsmjax.studies.control_comparison.ESTIMATOR_SCENARIOS]; refused where it makes
    no sense, [`check_estimator_scenario`][pmsmjax.studies.control_comparison.check_estimator_scenario]).

    Chapter 5 observers ([`pmsmjax.estimators.OBSERVERS`][pmsmjax.estimators.catalogue.OBSERVERS]) start from
    standstill with I/f; the chapter 6 estimators (``hfi-rotating``, ``hfi-pulsating``, ``hybrid``) run
    [`chapter6_drive`][pmsmjax.studies.control_comparison.chapter6_drive] (default motor the salient book
    motor) with the rotor ``initial_angle_deg`` electrical degrees off their initial estimate (default 0 for
    chapter 5, [`CHAPTER6_INITIAL_ANGLE_DEG`][pmsmjax.studies.control_comparison.CHAPTER6_INITIAL_ANGLE_DEG]
    for chapter 6).

    Each entry holds, on ``book``, the figures of
    [`run_control`][pmsmjax.studies.control_comparison.run_control] (rise, dip, ITAE, THD, ripple, ...), on
    the fixed scenarios those of
    [`run_estimator_scenario`][pmsmjax.studies.control_comparison.run_estimator_scenario]; and the observer's
    ([`pmsmjax.analysis.observer_errors.observer_errors`][pmsmjax.analysis.observer_errors.observer_errors]:
    angle error RMS/max after convergence in electrical degrees, **modulo pi for the injection estimators**
    (``angle_modulo``), speed estimation error RMS, speed tracking error RMS, ``lock_lost``, judged on the
    angle alone off the book scenario), plus, on ``book`` unless ``sweep`` is None, ``lowest_held_rpm`` under
    ``sweep.load_nm`` and the sweep's runs
    ([`low_speed_sweep`][pmsmjax.studies.control_comparison.low_speed_sweep]), and ``lowest_held_rpm_hot_r``
    with the plant's R off the observer's by ``sweep.hot_r_factor``. Returns the layout of
    [`compare_controllers`][pmsmjax.studies.control_comparison.compare_controllers] (``windows`` None off the
    book scenario).
    """
    settings.check()
    check_estimator_scenario(names, scenario)
    families = {name: estimator_family(name) for name in names}
    chapter6 = any(f != "ch5" for f in families.values())
    if initial_angle_deg is None:
        initial_angle_deg = CHAPTER6_INITIAL_ANGLE_DEG if chapter6 else 0.0
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
    for name, drive in drives.items():
        start = drive.init(theta_e=math.radians(initial_angle_deg))
        if fixed is None:
            run = run_control(name, drive, settings, start)
        else:
            run = run_estimator_scenario(drive, fixed, start)
        modulo_pi = families[name] == "injection"
        # off the book scenario the speed reference is (near) zero: lock is judged on the angle alone
        errors = observer_errors(run["trace"], drive.Ts, modulo_pi=modulo_pi, speed_lock=fixed is None)
        run["entry"].update(errors)
        run["entry"]["observer"] = name
        if sweep is not None and fixed is None:
            swept = low_speed_sweep(drive, sweep)
            run["entry"]["lowest_held_rpm"] = swept["lowest_held_rpm"]
            run["entry"]["low_speed_runs"] = swept["runs"]
            if sweep.hot_r_factor is not None:
                hot = low_speed_sweep(drive, sweep, sweep.hot_r_factor)
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
    ([`ESTIMATOR_COLUMNS`][pmsmjax.studies.control_comparison.ESTIMATOR_COLUMNS])."""
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
    """The observer table of [`compare_estimators`][pmsmjax.studies.control_comparison.compare_estimators]'s
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
