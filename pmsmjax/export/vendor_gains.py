"""What the vendor targets of ``pmsmjax export`` share: a vendor parameter (name, value, unit, meaning),
the conversions every vendor needs (the torque constant, the speed PI without active damping), the JSON
every vendor target writes next to its native file, and the refusal of a d-axis reference no vendor
parameter expresses.

The speed PI of the simulator (book ch. 3) is ``i_q* = kp e + x - B_a w`` with active damping ``B_a``.
Vendor velocity PIs have no active-damping term; the nearest they express is the PI with the same
feedback path, ``kp' = kp + B_a``: ``i_q* = kp' e + x`` differs from the simulator's only by
``B_a w*`` on the reference path. The closed loop's poles, its stability margins and its rejection of load
torque are the simulator's; a reference step sees the PI's zero ``ki / kp'`` (more overshoot than the
simulator's first-order response). Every vendor target writes ``kp'`` and says so.
"""

import dataclasses
import json
import math

from pmsmjax.export.description import ControllerDescription
from pmsmjax.spec.validation import ParameterError

__all__ = [
    "VendorParameter",
    "torque_constant_nm_per_a",
    "speed_kp_without_damping",
    "refuse_d_axis",
    "gains_json",
    "check_finite_positive",
    "write_files",
]


@dataclasses.dataclass(frozen=True)
class VendorParameter:
    """One parameter as the vendor names it.

    Attributes:
        name: the vendor's name (``axis0.controller.config.vel_gain``, ``PID_velocity.P``).
        value: its value in the vendor's unit (a number, or an enum's name as the vendor writes it).
        unit: the vendor's unit (``Nm/(turn/s)``), ``""`` for an enum or a count.
        meaning: how it comes from the simulator's gains (the formula).
    """

    name: str
    value: float | int | str
    unit: str
    meaning: str


def torque_constant_nm_per_a(d: ControllerDescription) -> float:
    """``k_t = 1.5 p psi_f``, N m per A of peak (amplitude-invariant) ``i_q``: the torque of the
    controller's motor model per q-axis ampere (surface-magnet torque; reluctance torque needs ``i_d``)."""
    return 1.5 * d.pole_pairs * d.psi_f_wb


def speed_kp_without_damping(d: ControllerDescription) -> float:
    """``kp + B_a``, A/(rad/s): the velocity PI's proportional gain with the simulator's active damping
    folded in (same feedback path; module docstring)."""
    return d.speed_kp + d.speed_active_damping


def refuse_d_axis(d: ControllerDescription, target: str, where: str) -> None:
    """Raise the one-line refusal when the drive's d-axis reference is not ``i_d* = 0`` (MTPA, field
    weakening): the vendor targets write the ``i_d = 0`` cascade's gains only."""
    if d.d_axis != "none":
        what = "MTPA" if d.d_axis == "mtpa" else "MTPA and voltage-feedback field weakening"
        raise ParameterError(
            f"--target {target}: {where} runs {what}, which the {target} parameters written here do not "
            f"express (they set the i_d = 0 cascade's gains); drop --field-weakening, or use --target c."
        )


def check_finite_positive(target: str, parameters: list[VendorParameter]) -> None:
    """Raise the one-line refusal when a numeric gain came out non-finite or not positive (a tuned gains
    file the vendor's discretisation cannot express)."""
    for p in parameters:
        if isinstance(p.value, float) and not (math.isfinite(p.value) and p.value > 0.0):
            raise ParameterError(
                f"--target {target}: {p.name} would be {p.value:.6g} ({p.meaning}); the {target} firmware "
                "needs a positive gain: raise the tuned proportional gain or lower the integral gain in "
                "--gains."
            )


def gains_json(
    target: str, d: ControllerDescription, parameters: list[VendorParameter], notes: list[str]
) -> str:
    """The JSON every vendor target writes: ``{"target", "source", "gains_source", "Ts_s", "parameters":
    {name: {"value", "unit", "meaning"}}, "notes"}``."""
    body = {
        "target": target,
        "source": d.source,
        "gains_source": d.gains_source,
        "Ts_s": d.Ts_s,
        "parameters": {p.name: {"value": p.value, "unit": p.unit, "meaning": p.meaning} for p in parameters},
        "notes": notes,
    }
    return json.dumps(body, indent=2) + "\n"


def write_files(files: dict[str, str], folder) -> list:
    """Write ``{file name: text}`` into the existing ``folder``, each atomically; returns their paths."""
    from pathlib import Path

    from pmsmjax.io.logs import atomic_write

    return [
        atomic_write(Path(folder) / name, lambda f, t=text: f.write(t), mode="w")
        for name, text in files.items()
    ]
