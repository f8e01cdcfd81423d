"""The keyword options the drive presets share (plant, limits, control period), written once with the
book's values as defaults: [`DRIVE_OPTIONS`][pmsmjax.presets.drive_options.DRIVE_OPTIONS], and the decorator
[`with_drive_options`][pmsmjax.presets.drive_options.with_drive_options] that gives a preset those of them
it takes.

A preset written as::

    @with_drive_options("frame", "u_dc", "n_substeps", n_substeps=1)
    def my_drive(motor=None, *, band_a: float = 0.5, **options) -> Drive:
        ...

is called as ``my_drive(band_a=0.4, u_dc=400.0)``; its signature (``help``, ``inspect.signature``) lists
``band_a`` and then the named options with their defaults (here ``n_substeps=1`` instead of the book's 10);
its body gets every named option in ``options``, the caller's value or the default; a keyword it does not
take is a TypeError, as for any function.
"""

import functools
import inspect

from pmsmjax.controllers.base import AbstractDAxisReference
from pmsmjax.presets.book_constants import (
    BOOK_CURRENT_BANDWIDTH,
    BOOK_CURRENT_LIMIT,
    BOOK_DC_LINK,
    BOOK_SPEED_BANDWIDTH,
    BOOK_TS,
)

__all__ = ["DRIVE_OPTIONS", "FOC_OPTIONS", "COMPARATOR_OPTIONS", "with_drive_options"]

#: The shared options, name -> (annotation, the book's default):
#:
#: - ``frame``: the machine model's frame (``"dq"``; the frames of each machine's presets).
#: - ``mechanics``: ``"dynamic"`` (the rotor's equation of motion) or ``"imposed"`` (speed set from outside).
#: - ``mode``: ``"speed"`` (the speed loop runs) or the controller's own without it (``"current"`` for the
#:   FOC drives and hysteresis, ``"torque"`` for DTC: the scenario sets that reference).
#: - ``current_bandwidth``: current-loop bandwidth of the design rule, rad/s.
#: - ``speed_bandwidth``: speed-loop bandwidth of the design rule, rad/s.
#: - ``current_limit``: peak phase-current limit, A.
#: - ``u_dc``: DC-link voltage, V.
#: - ``Ts``: control period, s.
#: - ``n_substeps``: RK4 sub-steps of the plant per period.
#: - ``computation_delay``: the voltage chosen in one period is applied in the next (a DSP's delay).
#: - ``speed_divider``: the speed loop runs every this many periods.
#: - ``d_axis``: a d-axis reference block (MTPA, field weakening); ``None``: i_d = 0 (the scenario's i_d*).
DRIVE_OPTIONS = {
    "frame": (str, "dq"),
    "mechanics": (str, "dynamic"),
    "mode": (str, "speed"),
    "current_bandwidth": (float, BOOK_CURRENT_BANDWIDTH),
    "speed_bandwidth": (float, BOOK_SPEED_BANDWIDTH),
    "current_limit": (float, BOOK_CURRENT_LIMIT),
    "u_dc": (float, BOOK_DC_LINK),
    "Ts": (float, BOOK_TS),
    "n_substeps": (int, 10),
    "computation_delay": (bool, True),
    "speed_divider": (int, 1),
    "d_axis": (AbstractDAxisReference | None, None),
}

#: The options of the book's FOC cascade ([`book_drive`][pmsmjax.presets.three_phase.book_drive] and its
#: variants).
FOC_OPTIONS = tuple(DRIVE_OPTIONS)
#: The options of the comparator drives (hysteresis, table DTC): no current loop, no d-axis block, and the
#: control period is the comparator's sample, which each of them names itself.
COMPARATOR_OPTIONS = (
    "frame", "mechanics", "mode", "speed_bandwidth", "current_limit", "u_dc", "n_substeps",
    "computation_delay",
)  # fmt: skip


def with_drive_options(*names: str, **defaults):
    """Decorator: the preset takes the options `names` of
    [`DRIVE_OPTIONS`][pmsmjax.presets.drive_options.DRIVE_OPTIONS] as keyword arguments after its own,
    defaulting to `defaults` where given, else to the book's values, and receives them all in its
    ``**options`` (see the module docstring)."""
    unknown = sorted(set(names) - set(DRIVE_OPTIONS)) + sorted(set(defaults) - set(names))
    if unknown:
        raise TypeError(f"with_drive_options: {', '.join(unknown)} not among the options named")
    shared = [
        inspect.Parameter(
            name,
            inspect.Parameter.KEYWORD_ONLY,
            default=defaults.get(name, DRIVE_OPTIONS[name][1]),
            annotation=DRIVE_OPTIONS[name][0],
        )
        for name in names
    ]

    def decorate(preset):
        own = inspect.signature(preset)
        params = [p for p in own.parameters.values() if p.kind is not inspect.Parameter.VAR_KEYWORD]
        signature = own.replace(parameters=[*params, *shared])

        @functools.wraps(preset)
        def with_options(*args, **kwargs):
            bound = signature.bind(*args, **kwargs)
            bound.apply_defaults()
            return preset(*bound.args, **bound.kwargs)

        with_options.__signature__ = signature
        return with_options

    return decorate
