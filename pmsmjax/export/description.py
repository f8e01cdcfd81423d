"""A built drive's controller as plain numbers: what a firmware controller needs to run exactly the
field-oriented control the simulator runs (the book, ch. 3).

[`describe`][pmsmjax.export.description.describe] reads a [`Drive`][pmsmjax.drive.Drive] whose controller is
the three-phase [`FOC`][pmsmjax.controllers.foc.FOC] cascade with the blocks export can write:

- the speed PI with active damping ([`SpeedLoopGains`][pmsmjax.controllers.speed_pi.SpeedLoopGains]), either
  anti-windup, any speed-loop divider, in speed mode;
- the dq current PIs with decoupling and delay compensation
  ([`CurrentLoopGains`][pmsmjax.controllers.current_pi.CurrentLoopGains]);
- the d-axis reference: none (the book's i_d = 0), [`MTPA`][pmsmjax.controllers.mtpa.MTPA], or
  [`VoltageFeedbackFieldWeakening`][pmsmjax.controllers.field_weakening.VoltageFeedbackFieldWeakening];
- [`DeadTimeCompensation`][pmsmjax.controllers.dead_time_compensation.DeadTimeCompensation] or none;
- the book's [`SVPWM`][pmsmjax.inverters.svpwm.SVPWM] modulator;
- a position sensor as the estimator (exact or encoder: the firmware gives its own sensor's angle and
  speed), no voltage injection.

Anything else (another current block such as a flux map's, a sensorless observer, another modulator) is
refused with one [`ParameterError`][pmsmjax.spec.validation.ParameterError] line saying what export writes.
Every number is rounded to float32 here, once, as the simulator's float32 run holds it; the constants the
simulator computes from them at run time (the speed loop's tracking gain ``Ts ki/kp``, the field-weakening
floor ``-min(I_max, psi_f/L_d)``) are computed in float32 in the same order.
"""

import dataclasses

import numpy as np

from pmsmjax.spec.validation import ParameterError

__all__ = ["ControllerDescription", "describe", "SUPPORTED", "f32"]

#: What export writes, for the refusals' messages.
SUPPORTED = (
    "the FOC cascade (--control pi: speed PI with active damping, dq current PIs with decoupling and "
    "delay compensation; i_d = 0, MTPA or --field-weakening; dead-time compensation; SVPWM) on a position "
    "sensor"
)


def f32(value) -> float:
    """``value`` rounded to float32, as a Python float (exactly representable in float32)."""
    return float(np.float32(np.asarray(value, dtype=np.float64)))


@dataclasses.dataclass(frozen=True)
class ControllerDescription:
    """The exported controller: float32 numbers (SI units) and the cascade's static choices.

    Attributes:
        source: the drive file or preset the drive came from.
        gains_source: the gains file whose gains replaced the design rules, or None (design rules).
        Ts_s: control (and PWM) period, s.
        computation_delay: the duties computed at ``t_k`` are applied from ``t_{k+1}`` (one period later).
        pole_pairs: pole pairs of the controller's motor model.
        R_ohm, L_d_h, L_q_h, psi_f_wb: the controller's motor model (decoupling, prediction, MTPA).
        current_limit_a: peak phase-current limit, A (``|i_dq*|`` stays inside it).
        speed_kp: speed PI proportional gain, A/(rad/s).
        speed_ki: speed PI integral gain, A/rad.
        speed_active_damping: active damping ``B_a``, A/(rad/s).
        speed_anti_windup: ``"realisable_reference"`` or ``"reset"``.
        speed_tracking: anti-windup tracking gain per speed-loop period (1 for ``"reset"``).
        speed_divider: the speed loop runs every this many control periods.
        speed_period_s: the speed loop's period, ``speed_divider * Ts``, s.
        current_kp_d, current_kp_q: current PI proportional gains, V/A.
        current_ki_d, current_ki_q: current PI integral gains, V/(A s).
        decoupling: the dq decoupling feed-forward is on.
        delay_compensation: with a computation delay, the current loop runs on the current predicted one
            period ahead.
        d_axis: ``"none"`` (i_d* = 0), ``"mtpa"`` or ``"field_weakening"``.
        fw_bandwidth_rad_s, fw_voltage_margin, fw_mtpa: the voltage-feedback field weakening's loop
            bandwidth, the fraction of the voltage limit it holds, and whether its base is MTPA.
        fw_id_min_a: the field weakening's floor of ``i_d*``, ``-min(I_max, psi_f/L_d)``, A.
        dead_time_s, device_drop_v, sign_current_a: the dead-time compensation's estimates (dead time, s;
            device drop, V; the current over which the sign is smoothed, ``tanh(i/i_eps)``, A); None
            without compensation.
        dead_time_current_source: ``"reference"`` or ``"measured"``, whose phase-current signs the
            compensation predicts.
        gains: ``{dotted name in the drive: value}`` of every gain written (the names of a gains file).
    """

    source: str
    gains_source: str | None
    Ts_s: float
    computation_delay: bool
    pole_pairs: int
    R_ohm: float
    L_d_h: float
    L_q_h: float
    psi_f_wb: float
    current_limit_a: float
    speed_kp: float
    speed_ki: float
    speed_active_damping: float
    speed_anti_windup: str
    speed_tracking: float
    speed_divider: int
    speed_period_s: float
    current_kp_d: float
    current_kp_q: float
    current_ki_d: float
    current_ki_q: float
    decoupling: bool
    delay_compensation: bool
    d_axis: str
    fw_bandwidth_rad_s: float | None
    fw_voltage_margin: float | None
    fw_mtpa: bool
    fw_id_min_a: float | None
    dead_time_s: float | None
    device_drop_v: float | None
    sign_current_a: float | None
    dead_time_current_source: str
    gains: dict

    @property
    def dead_time_compensation(self) -> bool:
        """Whether the controller adds the inverter's predicted voltage error back."""
        return self.dead_time_s is not None


def _refuse(what: str, where: str) -> ParameterError:
    return ParameterError(f"{where}: {what} cannot be exported; pmsmjax export writes {SUPPORTED}.")


def describe(
    drive, source: str, gains_source: str | None = None, where: str = "--motor"
) -> ControllerDescription:
    """The controller of ``drive`` as a
    [`ControllerDescription`][pmsmjax.export.description.ControllerDescription].

    Args:
        drive: a built three-phase [`Drive`][pmsmjax.drive.Drive] (gains already in place).
        source: the drive file or preset it was built from (for the generated files' header).
        gains_source: the gains file applied to it, or None for the design-rule gains.
        where: how a refusal names the drive's origin (``"--motor industrial-5k6w"``).

    Raises:
        ParameterError: one line, for a part of the drive export cannot write (module docstring).
    """
    from pmsmjax.controllers.current_pi import CurrentLoopGains
    from pmsmjax.controllers.field_weakening import VoltageFeedbackFieldWeakening
    from pmsmjax.controllers.foc import FOC
    from pmsmjax.controllers.mtpa import MTPA
    from pmsmjax.controllers.speed_pi import SpeedLoopGains
    from pmsmjax.estimators.position_sensors import Encoder, ExactSensor
    from pmsmjax.inverters.svpwm import SVPWM

    c = drive.controller
    if type(c) is not FOC:
        raise _refuse(f"the controller {type(c).__name__}", where)
    if c.mode != "speed":
        raise _refuse(f"a FOC in {c.mode} mode (the scenario's current references)", where)
    if type(c.speed) is not SpeedLoopGains:
        raise _refuse(f"the speed block {type(c.speed).__name__}", where)
    if type(c.current) is not CurrentLoopGains:
        raise _refuse(f"the current block {type(c.current).__name__}", where)
    if type(drive.modulator) is not SVPWM:
        raise _refuse(f"the modulator {type(drive.modulator).__name__}", where)
    if not isinstance(drive.estimator, (ExactSensor, Encoder)):
        raise _refuse(f"the estimator {type(drive.estimator).__name__} (a sensorless observer)", where)
    if c.d_axis is not None and type(c.d_axis) not in (MTPA, VoltageFeedbackFieldWeakening):
        raise _refuse(f"the d-axis reference {type(c.d_axis).__name__}", where)

    m = c.model
    Ts = float(drive.Ts)
    R, L_d, L_q, psi_f = (np.float32(f32(getattr(m, k))) for k in ("R", "L_d", "L_q", "psi_f"))
    limit = np.float32(f32(c.current_limit))
    s = c.speed
    kp, ki, b_a = (np.float32(f32(getattr(s, k))) for k in ("kp", "ki", "active_damping"))
    speed_period = Ts * c.speed_divider  # a Python float, as held_speed_step forms it
    if s.anti_windup == "realisable_reference":
        # realisable_reference_tracking: g = clip(Ts ki / kp, 0, 1), 1 for kp <= 0; float32 as at run time
        g = (np.float32(speed_period) * ki) / kp if kp > 0 else np.float32(1.0)
        tracking = f32(min(max(g, np.float32(0.0)), np.float32(1.0)))
    else:
        tracking = 1.0
    i = c.current
    gains = {
        "controller.speed.kp": f32(kp),
        "controller.speed.ki": f32(ki),
        "controller.speed.active_damping": f32(b_a),
        **{f"controller.current.{k}": f32(getattr(i, k)) for k in ("kp_d", "kp_q", "ki_d", "ki_q")},
    }
    fw = c.d_axis if isinstance(c.d_axis, VoltageFeedbackFieldWeakening) else None
    d_axis = "none" if c.d_axis is None else ("mtpa" if fw is None else "field_weakening")
    if fw is not None:
        gains["controller.d_axis.bandwidth"] = f32(fw.bandwidth)
        id_min = f32(-np.minimum(limit, psi_f / L_d))
    comp = c.dead_time_compensation
    estimate = None if comp is None else comp.estimate
    return ControllerDescription(
        source=str(source),
        gains_source=None if gains_source is None else str(gains_source),
        Ts_s=Ts,
        computation_delay=bool(drive.computation_delay),
        pole_pairs=int(m.pole_pairs),
        R_ohm=f32(R),
        L_d_h=f32(L_d),
        L_q_h=f32(L_q),
        psi_f_wb=f32(psi_f),
        current_limit_a=f32(limit),
        speed_kp=f32(kp),
        speed_ki=f32(ki),
        speed_active_damping=f32(b_a),
        speed_anti_windup=s.anti_windup,
        speed_tracking=tracking,
        speed_divider=int(c.speed_divider),
        speed_period_s=speed_period,
        current_kp_d=gains["controller.current.kp_d"],
        current_kp_q=gains["controller.current.kp_q"],
        current_ki_d=gains["controller.current.ki_d"],
        current_ki_q=gains["controller.current.ki_q"],
        decoupling=bool(c.decoupling),
        delay_compensation=bool(c.delay_compensation),
        d_axis=d_axis,
        fw_bandwidth_rad_s=None if fw is None else f32(fw.bandwidth),
        fw_voltage_margin=None if fw is None else f32(fw.voltage_margin),
        fw_mtpa=bool(fw is None or fw.mtpa),
        fw_id_min_a=None if fw is None else id_min,
        dead_time_s=None if estimate is None else f32(estimate.dead_time),
        device_drop_v=None if estimate is None else f32(estimate.device_drop),
        sign_current_a=None if estimate is None else f32(estimate.current_scale),
        dead_time_current_source="reference" if comp is None else comp.current_source,
        gains=gains,
    )
