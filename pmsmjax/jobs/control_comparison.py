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
current control; [`pmsmjax.jobs.equal_switching`][pmsmjax.jobs.equal_switching]) is run a second time, as
``"NAME@F kHz"``, with its bands scaled so that its mean switching frequency over the same window meets the
given frequency (by default the
PWM frequency ``1/Ts`` of the voltage-commanding controllers compared).

Voltage-commanding controllers run on the switching-resolved bridge by default (``bridge="switching"``):
with the averaged bridge the PWM ripple is not in the model, and its THD and torque ripple would read
near zero next to the hysteresis controller's, which switches in the model itself.

The observers side by side (``compare --estimator``) run on this module's figures:
[`pmsmjax.jobs.estimator_comparison`][pmsmjax.jobs.estimator_comparison].
"""

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np

from pmsmjax import presets
from pmsmjax.analysis import metrics
from pmsmjax.analysis.operating_point import run_flags
from pmsmjax.analysis.spectra import sampled_spectrum, thd
from pmsmjax.analysis.speed_step_summary import speed_step_summary
from pmsmjax.analysis.within_period import dense_window
from pmsmjax.assemble import with_parts
from pmsmjax.drive import Drive
from pmsmjax.frames.three_phase import inverse_park
from pmsmjax.inverters.switching import SwitchingBridge
from pmsmjax.jobs.equal_switching import BAND_LEAVES, match_switching_frequency
from pmsmjax.machines.motor import PMSMParameters
from pmsmjax.presets.control_methods import CONTROLS, control_drive
from pmsmjax.presets.five_phase import FIVE_PHASE_CONTROLS, five_phase_drive
from pmsmjax.presets.six_phase import SIX_PHASE_CONTROLS, six_phase_drive
from pmsmjax.simulate import check_simulation, simulate
from pmsmjax.spec.validation import ParameterError

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
        """Raise [`ParameterError`][pmsmjax.spec.validation.ParameterError] naming the first inconsistent
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
    ([`pmsmjax.spec.drive_spec.DriveSpec`][pmsmjax.spec.drive_spec.DriveSpec]) instead of ``motor``: its drive
    ([`pmsmjax.assemble.spec_drive`][pmsmjax.assemble.spec_drive]; a multi-phase switching bridge with the
    file's dead time)."""
    if spec is not None:
        from pmsmjax.assemble import spec_drive

        if machine != "three-phase":
            return spec_drive(spec, name, bridge=bridge)
        drive = spec_drive(spec, name)
    elif machine != "three-phase":
        preset = MULTIPHASE_PRESETS[machine][0]
        return preset(motor, control=name, bridge=bridge)
    else:
        drive = control_drive(name, motor)
    if bridge == "switching" and drive.controller.command_kind == "voltage":
        drive = with_parts(drive, {"bridge": SwitchingBridge(drive.bridge.u_dc)})
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
    [`machine_controls`][pmsmjax.jobs.control_comparison.machine_controls]) on the book scenario.

    With ``settings.equal_switching_hz`` each controller with bands is also run with its bands matched
    to that mean switching frequency (``0``: the PWM frequency of the voltage-commanding controllers,
    [`pwm_frequency_hz`][pmsmjax.jobs.control_comparison.pwm_frequency_hz]), under the name ``"NAME@F kHz"``;
    its entry adds ``band_factor`` and ``band_search_runs``.

    Returns ``{"settings", "controllers": name -> figures, "traces": name -> Trace, "windows": name ->
    {t, i_abc, torque, psi_ab}}``; `progress`: optional callable taking a line per controller; `adjust`:
    optional ``(drive, name) -> drive`` applied to each drive before anything runs (tuned gains, say);
    `spec`: a drive file ([`pmsmjax.spec.drive_spec.DriveSpec`][pmsmjax.spec.drive_spec.DriveSpec]) whose
    drives run instead of ``motor``'s presets
    ([`compared_drive`][pmsmjax.jobs.control_comparison.compared_drive]).
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
