"""``pmsmjax pwm-compare``: the PWM methods of a drive file's three-, six- or five-phase drive at one steady
operating point ([`pmsmjax.jobs.pwm_comparison`][pmsmjax.jobs.pwm_comparison]), from a
[`PwmCompareSpec`][pmsmjax.jobs.pwm_compare.PwmCompareSpec] to a
[`PwmCompareResult`][pmsmjax.jobs.pwm_compare.PwmCompareResult] (pwm.json's content, waveforms.npz's arrays
and what the figures need).

Importing this module loads no JAX: [`check_speed`][pmsmjax.jobs.pwm_compare.check_speed] and
[`check_operating_point`][pmsmjax.jobs.pwm_compare.check_operating_point] belong to the command's checks
before any work; [`compare_pwm`][pmsmjax.jobs.pwm_compare.compare_pwm] imports the engine when called.
"""

import dataclasses
import time
from collections.abc import Callable

from pmsmjax.spec.validation import ParameterError, plain

__all__ = [
    "BASE_CONTROL",
    "PwmCompareResult",
    "PwmCompareSpec",
    "check_operating_point",
    "check_speed",
    "compare_pwm",
]

#: Phase count -> the control whose drive reaches the operating point and its default modulator
#: ([`pmsmjax.jobs.pwm_comparison.PhaseCount.base_drive`][pmsmjax.jobs.pwm_comparison.PhaseCount]).
BASE_CONTROL = {
    3: ("pi", {}),
    6: ("conventional", {"pwm": "four-vector"}),
    5: ("conventional", {"pwm": "near-four-vector"}),
}


@dataclasses.dataclass(frozen=True)
class PwmCompareSpec:
    """What one PWM comparison is asked for (the command's flags, checked).

    - `drive`: the drive file ([`DriveSpec`][pmsmjax.spec.drive_spec.DriveSpec]) with `phases` phases.
    - `speed_rpm`, `load_nm`: the operating point; `dead_time_s`: the ``_deadtime`` variants' dead time.
    - `settle_cycles`, `window_cycles`: fundamental periods settled, then analysed.
    - `modulators`: the modulators compared; `bridges`: the bridge variants (None: the phase count's).
    - `gains`: the tuned gains file, as pwm.json reports it.
    """

    drive: object
    speed_rpm: float
    load_nm: float
    dead_time_s: float
    settle_cycles: int
    window_cycles: int
    modulators: tuple[str, ...]
    bridges: tuple[str, ...] | None = None
    phases: int = 3
    gains: str | None = None


@dataclasses.dataclass(frozen=True)
class PwmCompareResult:
    """What a PWM comparison gives its writer: `report` (pwm.json's content), `arrays` (waveforms.npz:
    ``"VARIANT/KEY"`` -> array) and `comparison`
    ([`pmsmjax.jobs.pwm_comparison.compare`][pmsmjax.jobs.pwm_comparison.compare]'s result, which the figures
    read)."""

    report: dict
    arrays: dict
    comparison: dict


def check_speed(drive, speed_rpm: float) -> None:
    """Refuse a speed whose fundamental period is not a whole number of the drive file ``drive``'s PWM
    periods (the spectra would leak), naming the four nearest whole r/min that fit; pure Python."""
    Ts = drive.Ts
    pole_pairs = drive.motor["pole_pairs"]
    f1 = speed_rpm / 60.0 * pole_pairs
    per_cycle = 1.0 / (f1 * Ts)
    if abs(per_cycle - round(per_cycle)) > 1e-9 * per_cycle:
        # whole r/min whose electrical period is a whole number of PWM periods, the four nearest the one asked
        step = 60.0 / (pole_pairs * Ts)  # r/min of a one-period electrical cycle
        whole = [
            step / n for n in range(1, 10 * round(per_cycle) + 10) if abs(step / n - round(step / n)) < 1e-9
        ]
        good = sorted(sorted(whole, key=lambda v: abs(v - speed_rpm))[:4])
        raise ParameterError(
            f"--speed-rpm {plain(speed_rpm)}: a fundamental period ({1e3 / f1:.4g} ms) is not a whole "
            f"number of {plain(Ts * 1e6)} us PWM periods, so the spectra would leak: pick a speed "
            f"with f_sw / f_1 whole, e.g. {', '.join(plain(round(g)) for g in good)} r/min."
        )


def check_operating_point(drive, speed_rpm: float, load_nm: float, u_dc_flag: str) -> None:
    """Refuse an operating point the drive file ``drive`` cannot hold with i_d = 0
    ([`pmsmjax.spec.steady_state.refuse_unreachable`][pmsmjax.spec.steady_state.refuse_unreachable]): the
    spectra of a saturated drive compare nothing. ``u_dc_flag``: the DC-link knob the fix names; pure
    Python."""
    from pmsmjax.spec.steady_state import refuse_unreachable

    refuse_unreachable(
        drive.motor,
        speed_rpm,
        load_nm,
        drive.u_dc_v,
        drive.voltage_limit_v,  # the default modulator's linear range for the phase count
        drive.current_limit_a,
        what="the PWM comparison",
        u_dc_flag=u_dc_flag,
        current_limit_flag="--current-limit",
    )


def compare_pwm(
    spec: PwmCompareSpec, adjust: Callable | None = None, progress: Callable[[str], None] | None = None
) -> PwmCompareResult:
    """Compare the modulators of ``spec`` on the drive file's drive
    ([`BASE_CONTROL`][pmsmjax.jobs.pwm_compare.BASE_CONTROL] of its phase count;
    [`pmsmjax.jobs.pwm_comparison.compare`][pmsmjax.jobs.pwm_comparison.compare]). ``adjust``:
    ``(drive, control) -> drive`` applied to the base drive (tuned gains, say); ``progress``: takes a line per
    variant."""
    from pmsmjax.assemble import spec_drive
    from pmsmjax.jobs.pwm_comparison import CompareSettings, compare

    settings = CompareSettings(
        speed_rpm=spec.speed_rpm,
        load_nm=spec.load_nm,
        dead_time_s=spec.dead_time_s,
        settle_cycles=spec.settle_cycles,
        window_cycles=spec.window_cycles,
        modulators=spec.modulators,
        bridges=spec.bridges,
        phases=spec.phases,
    )
    control, options = BASE_CONTROL[spec.phases]
    base = spec_drive(spec.drive, control, **options)
    if adjust is not None:
        base = adjust(base, control)
    t0 = time.perf_counter()
    result = compare(settings, base=base, progress=progress)
    report = {"settings": result["settings"], "entries": result["entries"]}
    report["settings"]["gains"] = spec.gains
    report["drive_file"] = spec.drive.summary()
    report["wall_time_s"] = time.perf_counter() - t0
    arrays = {f"{name}/{key}": v for name, w in result["waves"].items() for key, v in w.items()}
    return PwmCompareResult(report=report, arrays=arrays, comparison=result)
