"""The book's reference motor, drive and scenario, and motor files.

Their numbers (docs/book_reference.md, chapters 1-6: the surface motor and its salient variant for HF
injection, 311 V, 10 kHz, the 1000 r/min step with a 10 N m load at 0.2 s) are
[`pmsmjax.presets.book_constants`][pmsmjax.presets.book_constants].
Drives: [`book_drive`][pmsmjax.presets.three_phase.book_drive] (FOC, SVPWM) and
[`hysteresis_drive`][pmsmjax.presets.three_phase.hysteresis_drive] (hysteresis current control).
"""

from pathlib import Path

from pmsmjax.controllers.design import current_loop_imc, speed_loop_active_damping
from pmsmjax.controllers.dtc import SwitchingTableDTC
from pmsmjax.controllers.field_weakening import VoltageFeedbackFieldWeakening
from pmsmjax.controllers.foc import FOC
from pmsmjax.controllers.hysteresis import HysteresisCurrentControl
from pmsmjax.controllers.pr import pr_design
from pmsmjax.controllers.smc import smc_design
from pmsmjax.controllers.smc_dtc import SlidingModeDTC, smc_dtc_design
from pmsmjax.drive import Drive
from pmsmjax.estimators.flux_observer import StatorFluxObserver
from pmsmjax.inverters.averaged import AveragedBridge
from pmsmjax.inverters.svpwm import SVPWM
from pmsmjax.io.drive_files import MOTOR_FIELDS  # noqa: F401 (public here)
from pmsmjax.machines.motor import PMSMParameters
from pmsmjax.machines.pmsm3 import PMSMabc, PMSMAlphaBeta, PMSMdq
from pmsmjax.presets.book_constants import (
    BOOK_CURRENT_BANDWIDTH,
    BOOK_DURATION_S,
    BOOK_LOAD_NM,
    BOOK_LOAD_TIME_S,
    BOOK_MOTOR,
    BOOK_SALIENT_MOTOR,
    BOOK_SPEED_STEP_RPM,
    BOOK_TS,
    DTC_SAMPLE_PERIOD_S,
    HYSTERESIS_SAMPLE_PERIOD_S,
)
from pmsmjax.presets.drive_options import COMPARATOR_OPTIONS, FOC_OPTIONS, with_drive_options
from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.spec.validation import ParameterError, check_positive
from pmsmjax.units import rpm_to_rad_s

#: Resonator damping of the PR drive, rad/s: Kr = a_c R / w_c = 527 V/A, a peak gain Kp + Kr = 533 V/A,
#: which keeps the 1000 r/min, 10 N m fundamental error near 0.5 % (pmsmjax.controllers.pr.pr_design).
PR_W_C = 2.0


def book_motor(salient: bool = False) -> PMSMParameters:
    """The book's three-phase PMSM (surface; ``salient=True``: L_q = 12 mH for HF injection); the values
    are [`pmsmjax.presets.book_constants.BOOK_MOTOR`][pmsmjax.presets.book_constants.BOOK_MOTOR] and
    ``BOOK_SALIENT_MOTOR``."""
    return PMSMParameters(**(BOOK_SALIENT_MOTOR if salient else BOOK_MOTOR))


MOTORS = {"book": lambda: book_motor(False), "book_salient": lambda: book_motor(True)}

_MACHINE_FRAMES = {"dq": PMSMdq, "alpha_beta": PMSMAlphaBeta, "abc": PMSMabc}


def make_machine(motor: PMSMParameters, frame: str = "dq", mechanics: str = "dynamic"):
    """The machine model of ``motor`` in ``frame`` (``"dq"``, ``"alpha_beta"`` or ``"abc"``)."""
    if frame not in _MACHINE_FRAMES:
        raise ParameterError(f"frame must be one of {sorted(_MACHINE_FRAMES)}, got {frame!r}.")
    return _MACHINE_FRAMES[frame](motor, mechanics=mechanics)


@with_drive_options(*FOC_OPTIONS)
def book_drive(motor: PMSMParameters | None = None, **options) -> Drive:
    """The book's FOC drive: design-rule PI gains, SVPWM, averaged bridge, dq machine; the keyword options
    are those of [`FOC_OPTIONS`][pmsmjax.presets.drive_options.FOC_OPTIONS], the book's by default.

    The controller's motor model is the plant's motor (pass a different ``FOC.model`` to study
    mismatch); gains follow [`current_loop_imc`][pmsmjax.controllers.design.current_loop_imc] and
    [`speed_loop_active_damping`][pmsmjax.controllers.design.speed_loop_active_damping]. ``d_axis``: a d-axis
    reference block ([`MTPA`][pmsmjax.controllers.mtpa.MTPA],
    [`VoltageFeedbackFieldWeakening`][pmsmjax.controllers.field_weakening.VoltageFeedbackFieldWeakening]);
    ``None`` is i_d = 0 control (the scenario's ``i_d*``).
    """
    motor = book_motor() if motor is None else motor
    speed = speed_loop_active_damping(motor, options.pop("speed_bandwidth"))
    current = current_loop_imc(motor, options.pop("current_bandwidth"))
    return _foc_drive(motor, speed, current, **options)


def _foc_drive(motor, speed, current, *, current_limit, d_axis, mode, speed_divider, **plant) -> Drive:
    """The FOC drive of [`book_drive`][pmsmjax.presets.three_phase.book_drive] with the given speed and
    current blocks (the variants of the book's cascade: [`smc_drive`][pmsmjax.presets.three_phase.smc_drive],
    [`pr_drive`][pmsmjax.presets.three_phase.pr_drive]), SVPWM on the averaged bridge; ``plant``: the
    options of [`_averaged_drive`][pmsmjax.presets.three_phase._averaged_drive]."""
    controller = FOC(
        model=motor,
        speed=speed,
        current=current,
        current_limit=current_limit,
        d_axis=d_axis,
        mode=mode,
        speed_divider=speed_divider,
    )
    return _averaged_drive(motor, controller, SVPWM(), **plant)


def _averaged_drive(
    motor, controller, modulator, *, frame, mechanics, u_dc, Ts, n_substeps, computation_delay, **parts
) -> Drive:
    """The three-phase drive of ``controller`` and ``modulator`` (None: the controller's switch states
    drive the legs) on the averaged bridge at ``u_dc`` V, the machine ``motor`` in ``frame``; ``parts``:
    the drive's other parts (its estimator)."""
    return Drive(
        machine=make_machine(motor, frame, mechanics),
        controller=controller,
        modulator=modulator,
        bridge=AveragedBridge(u_dc),
        Ts=Ts,
        n_substeps=n_substeps,
        computation_delay=computation_delay,
        **parts,
    )


def _comparator_speed_divider(sample_period_s: float, speed_period_s: float) -> int:
    """The comparator drives' speed loop runs on a whole number of samples: its period is this divider
    times ``sample_period_s`` (both periods checked)."""
    check_positive("sample_period_s (comparator sample period)", sample_period_s, "s")
    check_positive("speed_period_s (speed-loop period)", speed_period_s, "s")
    return max(1, round(speed_period_s / sample_period_s))


def _speed_loop(options: dict, speed_divider: int) -> dict:
    """The speed-loop keywords of the controllers that hold their own design-rule speed PI (hysteresis,
    table and sliding-mode DTC), taken out of a preset's `options`: ``mode``, ``speed_bandwidth`` (rad/s)
    and ``speed_divider`` (control periods per speed-loop period)."""
    return {
        "mode": options.pop("mode"),
        "speed_divider": speed_divider,
        "speed_bandwidth": options.pop("speed_bandwidth"),
    }


@with_drive_options(*FOC_OPTIONS)
def smc_drive(
    motor: PMSMParameters | None = None,
    *,
    switching: str = "sign",
    time_constant_s: float = 0.02,
    reaching_ratio: float = 5.0,
    load_torque_rate_nm_s: float = 1000.0,
    margin: float = 1.2,
    **options,
) -> Drive:
    """The book's FOC drive ([`book_drive`][pmsmjax.presets.three_phase.book_drive]) with the sliding-mode
    speed block (the book, ch. 3).

    The keyword options are [`book_drive`][pmsmjax.presets.three_phase.book_drive]'s (frame, Ts,
    current_limit, current_bandwidth, ...; its ``speed_bandwidth`` is unused). The sliding-mode gains follow
    [`pmsmjax.controllers.smc.smc_design`][pmsmjax.controllers.smc.smc_design] from the same motor, current
    limit, current-loop bandwidth and speed-loop period: defaults c = 50 1/s (20 ms surface time constant),
    q = 250 1/s, eps = 4.2e5 rad/s^3 (10 N m in 10 ms plus friction, 20 % margin), boundary 1.39e3 rad/s^2.
    """
    motor = book_motor() if motor is None else motor
    options.pop("speed_bandwidth")  # the sliding-mode law replaces the PI speed loop
    current_bandwidth = options.pop("current_bandwidth")
    speed = smc_design(
        motor,
        time_constant_s,
        reaching_ratio=reaching_ratio,
        load_torque_rate_nm_s=load_torque_rate_nm_s,
        current_limit_a=options["current_limit"],
        current_bandwidth_rad_s=current_bandwidth,
        Ts=options["Ts"] * options["speed_divider"],
        margin=margin,
        switching=switching,
    )
    return _foc_drive(motor, speed, current_loop_imc(motor, current_bandwidth), **options)


#: Hysteresis drive defaults: full band, A; comparator sample period, s; speed-loop period, s (the book's
#: 10 kHz). See [`hysteresis_drive`][pmsmjax.presets.three_phase.hysteresis_drive] for why.
HYSTERESIS_BAND_A = 0.5
HYSTERESIS_SPEED_PERIOD_S = BOOK_TS


@with_drive_options(*COMPARATOR_OPTIONS, n_substeps=1, computation_delay=False)
def hysteresis_drive(
    motor: PMSMParameters | None = None,
    *,
    band_a: float = HYSTERESIS_BAND_A,
    sample_period_s: float = HYSTERESIS_SAMPLE_PERIOD_S,
    speed_period_s: float = HYSTERESIS_SPEED_PERIOD_S,
    comparator: str = "exact",
    smooth_width_a: float = 0.05,
    **options,
) -> Drive:
    """The book's motor under hysteresis current control (the book, ch. 3) with the design-rule speed PI.

    No modulator: the comparator's switch states drive the legs directly, held for one comparator sample
    ``sample_period_s``; the averaged bridge is exact for a held switch state (the period-average
    voltage of a constant state is that state's voltage). The speed loop runs every
    ``round(speed_period_s / sample_period_s)`` samples (10 at 10 us: the book's 10 kHz).

    Choices:

    - `n_substeps` = 1: one RK4 step of 10 us spans 0.004 rad of electrical angle at 1000 r/min and
      1/550 of the winding time constant, so its local error is below 1e-12 relative;
      tests/controllers/test_hysteresis.py checks the switch sequence and currents against scipy ``solve_ivp``
      at rtol 1e-10.
    - `band_a` = 0.5 A: at 10 us sampling it switches at 12 kHz per leg on average (transitions / 2;
      11-14 kHz in the phases of the book scenario), about the 10 kHz carrier of
      [`book_drive`][pmsmjax.presets.three_phase.book_drive], so the two are compared at about equal switching
      losses; it keeps the phase-current error within 0.8 A peak (0.23 A RMS) at 1000 r/min with 10 N m. It is
      also about the narrowest band that still sets the ripple: one 10 us sample moves the current by up
      to 0.6 A at that point, and below about 0.5 A the sampling takes over (0.25 A: 1.8x the switching
      frequency of 0.5 A instead of 2x, peak error twice the band).
    - `computation_delay` = False: hysteresis comparators are analog circuits or FPGA logic whose
      latency (well under 1 us) is small next to the sample, so a state acts from the sample that chose
      it. A DSP-style one-sample delay (``True``) lets the current run on for one more sample past the
      band: at 0.5 A and 10 us the RMS error grows from 0.23 A to 0.42 A and the peak from 0.77 A to
      1.3 A (book scenario, last 0.1 s).
    """
    divider = _comparator_speed_divider(sample_period_s, speed_period_s)
    motor = book_motor() if motor is None else motor
    controller = HysteresisCurrentControl(
        motor,
        band_a,
        options.pop("current_limit"),
        comparator=comparator,
        smooth_width_a=smooth_width_a,
        **_speed_loop(options, divider),
    )
    return _averaged_drive(motor, controller, None, Ts=sample_period_s, **options)


@with_drive_options(*(o for o in FOC_OPTIONS if o != "d_axis"))
def field_weakening_drive(
    motor: PMSMParameters | None = None,
    *,
    field_weakening_bandwidth: float | None = None,
    voltage_margin: float = 0.95,
    **options,
) -> Drive:
    """[`book_drive`][pmsmjax.presets.three_phase.book_drive] with MTPA and voltage-feedback field weakening,
    for speeds above base speed.

    With the book's 311 V link the i_d = 0 drive runs out of voltage at 1995 r/min under 15 A and at
    2321 r/min at no load; this one reaches 3000 r/min (tests/controllers/test_field_weakening.py).
    ``field_weakening_bandwidth`` (rad/s) defaults to a third of the current-loop bandwidth (367 rad/s for
    the book's 1100 rad/s; 50 to 800 rad/s all reach 2500 and 3000 r/min, the slower ones touching the
    voltage limit more often on the way). The other keyword options are
    [`book_drive`][pmsmjax.presets.three_phase.book_drive]'s.
    """
    fw = field_weakening_block(options["current_bandwidth"], field_weakening_bandwidth, voltage_margin)
    return book_drive(motor, d_axis=fw, **options)


def field_weakening_block(
    current_bandwidth: float = BOOK_CURRENT_BANDWIDTH,
    field_weakening_bandwidth: float | None = None,
    voltage_margin: float = 0.95,
) -> VoltageFeedbackFieldWeakening:
    """MTPA plus voltage-feedback field weakening whose voltage loop runs at ``field_weakening_bandwidth``
    (rad/s; default a third of the current loop's ``current_bandwidth``), holding ``voltage_margin`` of the
    modulator's linear limit (see
    [`field_weakening_drive`][pmsmjax.presets.three_phase.field_weakening_drive])."""
    if field_weakening_bandwidth is None:
        field_weakening_bandwidth = current_bandwidth / 3.0
    return VoltageFeedbackFieldWeakening(field_weakening_bandwidth, voltage_margin, mtpa=True)


@with_drive_options(*FOC_OPTIONS)
def pr_drive(
    motor: PMSMParameters | None = None,
    *,
    w_c: float = PR_W_C,
    discretisation: str = "tustin-prewarp",
    phase_lead: bool = True,
    back_emf_feedforward: bool = True,
    **options,
) -> Drive:
    """The book drive with the proportional-resonant current loop in alpha-beta (the book, ch. 3).

    Same speed loop, limits, modulator, bridge and machine as
    [`book_drive`][pmsmjax.presets.three_phase.book_drive] (its keyword options); the current block is
    [`pmsmjax.controllers.pr.pr_design`][pmsmjax.controllers.pr.pr_design] at the same current bandwidth, with
    resonator damping ``w_c`` (rad/s) and the given static options.
    """
    motor = book_motor() if motor is None else motor
    speed = speed_loop_active_damping(motor, options.pop("speed_bandwidth"))
    current = pr_design(
        motor,
        options.pop("current_bandwidth"),
        w_c,
        discretisation=discretisation,
        phase_lead=phase_lead,
        back_emf_feedforward=back_emf_feedforward,
    )
    return _foc_drive(motor, speed, current, **options)


def book_scenario(
    speed_rpm: float = BOOK_SPEED_STEP_RPM,
    load_nm: float = BOOK_LOAD_NM,
    load_time_s: float = BOOK_LOAD_TIME_S,
    duration_s: float = BOOK_DURATION_S,
) -> Scenario:
    """Speed step to ``speed_rpm`` at t = 0, load step 0 -> ``load_nm`` at ``load_time_s``."""
    return Scenario(
        duration_s=duration_s,
        speed_ref=Profile.constant(rpm_to_rad_s(speed_rpm)),
        load_torque=Profile.step(load_time_s, 0.0, load_nm),
    )


def load_motor(name_or_path: str | Path, *, check_units: bool = True) -> PMSMParameters:
    """A three-phase motor by preset name (``book``, ``book_salient``, ``servo-400w``, ...) or from a
    drive file ([`pmsmjax.io.drive_files`][pmsmjax.io.drive_files]; a seven-value motor file is one).

    The file holds ``R, L_d, L_q, psi_f, pole_pairs, J, B`` under ``[motor]`` (or, for a motor file, at
    top level), SI units: ohm, H, H, Wb, -, kg m^2, N m s; values implausible in those units (an
    inductance in mH) are refused unless ``check_units=False`` or the file says ``trust_units = true``.
    """
    key = str(name_or_path)
    if key in MOTORS:  # the book's motors as the presets build them
        return MOTORS[key]()
    from pmsmjax.io.drive_files import drive_spec

    values = drive_spec(name_or_path, check_units=check_units).motor
    return PMSMParameters(**{f: values[f] for f in MOTOR_FIELDS})


#: Table DTC defaults (see [`dtc_drive`][pmsmjax.presets.three_phase.dtc_drive]): comparator sample period s,
#: torque band N m, flux band Wb, speed-loop period s, flux-observer crossover rad/s.
DTC_TORQUE_BAND_NM = 1.0
DTC_FLUX_BAND_WB = 0.01
DTC_SPEED_PERIOD_S = BOOK_TS
FLUX_OBSERVER_CROSSOVER = 50.0


@with_drive_options(*COMPARATOR_OPTIONS, n_substeps=1, computation_delay=False)
def dtc_drive(
    motor: PMSMParameters | None = None,
    *,
    sample_period_s: float = DTC_SAMPLE_PERIOD_S,
    torque_band_nm: float = DTC_TORQUE_BAND_NM,
    flux_band_wb: float = DTC_FLUX_BAND_WB,
    torque_levels: int = 3,
    flux_ref_wb: float | None = None,
    speed_period_s: float = DTC_SPEED_PERIOD_S,
    crossover_rad_s: float = FLUX_OBSERVER_CROSSOVER,
    **options,
) -> Drive:
    """The book's motor under switching-table DTC (the book, ch. 4) with the design-rule speed PI.

    [`SwitchingTableDTC`][pmsmjax.controllers.dtc.SwitchingTableDTC] on the flux and torque of a
    [`StatorFluxObserver`][pmsmjax.estimators.flux_observer.StatorFluxObserver] (voltage model blended with
    the current model below ``crossover_rad_s``; the exact position sensor); no modulator, the table's leg
    states held for one comparator sample ``sample_period_s``; the speed loop every ``round(speed_period_s /
    sample_period_s)`` samples (4 at 25 us: the book's 10 kHz).

    Choices (measured on the book scenario, tests/controllers/test_dtc.py and README.md):

    - `sample_period_s` = 25 us (40 kHz), inside the usual 20-50 us of DTC implementations.
    - `torque_band_nm` = 1 N m and `flux_band_wb` = 10 mWb (5.5 % of psi_f): about twice what one 25 us
      sample moves the torque (0.4-0.65 N m) and the flux magnitude (up to 4.5 mWb) at 1000 r/min under
      10 N m. Narrower bands buy switching, not ripple, at this sample period: halving them raises the
      mean switching frequency from 4.4 to 8.1 kHz for the same 0.34 N m RMS torque ripple; doubling them
      gives 2.4 kHz and 0.46 N m (benchmarks/bench_dtc.py).
    - `n_substeps` = 1: one RK4 step of 25 us spans 0.01 rad of electrical angle at 1000 r/min and
      1/220 of the winding time constant.
    - `computation_delay` = False: as for hysteresis current control, a state acts from the sample that
      chose it (FPGA-style comparators); ``True`` gives the DSP's one-sample delay.
    """
    divider = _comparator_speed_divider(sample_period_s, speed_period_s)
    motor = book_motor() if motor is None else motor
    controller = SwitchingTableDTC(
        motor,
        torque_band_nm,
        flux_band_wb,
        options.pop("current_limit"),
        flux_ref_wb=flux_ref_wb,
        torque_levels=torque_levels,
        **_speed_loop(options, divider),
    )
    observer = StatorFluxObserver(motor, crossover_rad_s)
    return _averaged_drive(motor, controller, None, Ts=sample_period_s, estimator=observer, **options)


@with_drive_options(*(o for o in FOC_OPTIONS if o not in ("current_bandwidth", "d_axis")))
def smc_dtc_drive(
    motor: PMSMParameters | None = None,
    *,
    switching: str = "saturation",
    torque_rate_nm_per_ms: float = 10.0,
    flux_rate_wb_per_s: float = 20.0,
    torque_bandwidth: float = 2000.0,
    flux_bandwidth: float = 2000.0,
    flux_ref_wb: float | None = None,
    crossover_rad_s: float = FLUX_OBSERVER_CROSSOVER,
    **options,
) -> Drive:
    """The book's motor under sliding-mode DTC with SVPWM (the book, ch. 4) and the design-rule speed PI.

    [`SlidingModeDTC`][pmsmjax.controllers.smc_dtc.SlidingModeDTC] with the gains of
    [`pmsmjax.controllers.smc_dtc.smc_dtc_design`][pmsmjax.controllers.smc_dtc.smc_dtc_design] (torque slew 10
    N m/ms, flux slew 20 Wb/s, 2000 rad/s inside the boundary layers: K_T = 47.9 V, phi_T = 5.0 N m, K_psi =
    20 V, phi_psi = 10 mWb on the book motor), on the same
    [`StatorFluxObserver`][pmsmjax.estimators.flux_observer.StatorFluxObserver] as
    [`dtc_drive`][pmsmjax.presets.three_phase.dtc_drive]; SVPWM, averaged bridge, 10 kHz, one-period
    computational delay and 10 RK4 sub-steps as [`book_drive`][pmsmjax.presets.three_phase.book_drive].
    `switching`: ``"saturation"`` (default), ``"sign"`` or ``"tanh"``.
    """
    motor = book_motor() if motor is None else motor
    gains = smc_dtc_design(
        motor,
        torque_rate_nm_per_ms=torque_rate_nm_per_ms,
        flux_rate_wb_per_s=flux_rate_wb_per_s,
        torque_bandwidth_rad_s=torque_bandwidth,
        flux_bandwidth_rad_s=flux_bandwidth,
        Ts=options["Ts"],
    )
    controller = SlidingModeDTC(
        motor,
        current_limit=options.pop("current_limit"),
        flux_ref_wb=flux_ref_wb,
        switching=switching,
        **_speed_loop(options, options.pop("speed_divider")),
        **gains,
    )
    observer = StatorFluxObserver(motor, crossover_rad_s)
    return _averaged_drive(motor, controller, SVPWM(), estimator=observer, **options)
