"""What the six- and five-phase presets share: their drive function, one signature and one body
([`multiphase_drive_function`][pmsmjax.presets.multiphase.multiphase_drive_function]), which each machine's
module makes from its own motor, modulators, machine models and current blocks
(`pmsmjax.presets.six_phase.six_phase_drive`, `pmsmjax.presets.five_phase.five_phase_drive`): the n-leg
bridge, the FOC cascade with the design-rule speed PI around the machine's current block.
"""

from collections.abc import Callable

from pmsmjax.controllers.design import speed_loop_active_damping
from pmsmjax.controllers.multiphase import MultiPhaseFOC
from pmsmjax.drive import Drive
from pmsmjax.frames.multiphase import PhaseLayout
from pmsmjax.inverters.multiphase_bridges import MultiPhaseAveragedBridge, MultiPhaseSwitchingBridge
from pmsmjax.machines.multiphase_motor import MultiPhaseParameters
from pmsmjax.presets.drive_options import FOC_OPTIONS, with_drive_options
from pmsmjax.presets.three_phase import PR_W_C
from pmsmjax.spec.registry import REGISTRY
from pmsmjax.spec.validation import ParameterError

__all__ = [
    "MULTIPHASE_OPTIONS",
    "machine_controls",
    "multiphase_bridge",
    "multiphase_drive_function",
    "multiphase_machine",
]

#: The shared keyword options the multi-phase drives take: the book cascade's, without a d-axis block.
MULTIPHASE_OPTIONS = tuple(o for o in FOC_OPTIONS if o != "d_axis")


def machine_controls(machine: str) -> dict[str, str]:
    """The control schemes of ``machine`` by name -> one-line description
    (`pmsmjax.spec.registry.REGISTRY`)."""
    return {m.name: m.description for m in REGISTRY if m.kind == "control" and machine in m.machines}


def multiphase_machine(
    machine: str, frames: dict, motor, frame: str, mechanics: str, resistance_scale, **layout
):
    """The model of ``motor`` in ``frame``, one of ``frames`` (name -> class) of the multi-phase
    ``machine``; ``layout``: the phase layout keyword the classes need beyond their default one."""
    if frame not in frames:
        raise ParameterError(f"{machine} frame must be one of {', '.join(frames)}, got {frame!r}.")
    return frames[frame](motor, **layout, mechanics=mechanics, resistance_scale=resistance_scale)


def multiphase_bridge(bridge: str, u_dc: float, dead_time: float | None, layout: PhaseLayout):
    """The n-leg bridge of ``layout`` at ``u_dc`` V: ``averaged``, or ``switching`` with an optional
    ``dead_time`` s."""
    if bridge == "averaged":
        if dead_time is not None:
            raise ParameterError("dead_time needs the switching-resolved bridge: set bridge='switching'.")
        return MultiPhaseAveragedBridge(u_dc, layout)
    if bridge == "switching":
        return MultiPhaseSwitchingBridge(u_dc, dead_time=dead_time, layout=layout)
    raise ParameterError(f"bridge must be 'averaged' or 'switching', got {bridge!r}.")


def multiphase_drive_function(
    name: str,
    module: str,
    doc: str,
    *,
    machine: str,
    layout: PhaseLayout,
    default_motor: Callable[[], MultiPhaseParameters],
    pwms: dict,
    default_pwm: str,
    machine_model: Callable,
    current_block: Callable,
):
    """The drive function ``module.name`` (docstring `doc`) of the multi-phase ``machine`` (``"six-phase"``):
    `default_motor` when none is given, a modulator of `pwms` (name -> constructor; `default_pwm` by
    default), the machine model ``machine_model(motor, frame, mechanics, resistance_scale)`` and the current
    block ``current_block(control, motor, current_bandwidth, w_c)``, the n-leg bridge of ``layout``; the
    shared keyword options are [`MULTIPHASE_OPTIONS`][pmsmjax.presets.multiphase.MULTIPHASE_OPTIONS]."""

    @with_drive_options(*MULTIPHASE_OPTIONS)
    def drive(
        motor: MultiPhaseParameters | None = None,
        *,
        control: str = "vsd",
        pwm: str = default_pwm,
        bridge: str = "averaged",
        w_c: float = PR_W_C,
        dead_time: float | None = None,
        resistance_scale=None,
        **options,
    ) -> Drive:
        motor = default_motor() if motor is None else motor
        if pwm not in pwms:
            raise ParameterError(f"{machine} pwm must be one of {', '.join(pwms)}, got {pwm!r}.")
        plant = machine_model(motor, options["frame"], options["mechanics"], resistance_scale)
        current = current_block(control, motor, options["current_bandwidth"], w_c)
        modulator = pwms[pwm]()
        inverter = multiphase_bridge(bridge, options["u_dc"], dead_time, layout)
        controller = MultiPhaseFOC(
            model=motor,
            speed=speed_loop_active_damping(motor, options["speed_bandwidth"]),
            current=current,
            current_limit=options["current_limit"],
            mode=options["mode"],
            speed_divider=options["speed_divider"],
        )
        return Drive(
            plant,
            controller,
            modulator,
            inverter,
            Ts=options["Ts"],
            n_substeps=options["n_substeps"],
            computation_delay=options["computation_delay"],
        )

    drive.__name__ = drive.__qualname__ = name
    drive.__module__ = module
    drive.__doc__ = doc
    return drive
