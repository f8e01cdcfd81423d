"""Control methods by name: the one registry behind ``pmsmjax demo --control``, ``pmsmjax compare`` and
``pmsmjax tune --control``.

Each name maps to the preset that builds its drive on a given motor ([`pmsmjax.presets`][pmsmjax.presets]); a
later chapter adds its method here and every command gains it.
"""

import inspect

from pmsmjax import presets
from pmsmjax.checks.validation import ParameterError
from pmsmjax.drive import Drive
from pmsmjax.machines.motor import PMSMParameters

#: Control name -> (preset building its drive, one-line description).
CONTROLS = {
    "pi": (presets.book_drive, "cascaded PI FOC, i_d = 0 (book ch. 3)"),
    "smc": (presets.smc_drive, "sliding-mode speed loop, exponential reaching law, dq PI currents (ch. 3)"),
    "pr": (presets.pr_drive, "proportional-resonant current loops in alpha-beta, PI speed loop (ch. 3)"),
    "hysteresis": (presets.hysteresis_drive, "hysteresis current comparators, PI speed loop (ch. 3)"),
    "dtc": (presets.dtc_drive, "switching-table direct torque control, flux observer, PI speed loop (ch. 4)"),
    "smc-dtc": (
        presets.smc_dtc_drive,
        "sliding-mode direct torque control with SVPWM, PI speed loop (ch. 4)",
    ),
}


def control_options(name: str) -> tuple[str, ...]:
    """Keyword options the preset of control ``name`` accepts (those of
    [`presets.book_drive`][pmsmjax.presets.three_phase.book_drive] too when the preset passes its extra
    keywords on to it)."""
    preset = CONTROLS[name][0]
    params = inspect.signature(preset).parameters
    names = [p for p, v in params.items() if v.kind == v.KEYWORD_ONLY]
    if any(v.kind == v.VAR_KEYWORD for v in params.values()):
        names += [p for p in control_options("pi") if p not in names]
    return tuple(names)


def control_drive(name: str, motor: PMSMParameters | None = None, **options) -> Drive:
    """The drive of control ``name`` on ``motor`` (default the book motor), with preset ``options``.

    An option the preset does not take is refused with the list of those it does.
    """
    if name not in CONTROLS:
        raise ParameterError(f"unknown control {name!r}: choose from {', '.join(CONTROLS)}.")
    allowed = control_options(name)
    bad = sorted(set(options) - set(allowed))
    if bad:
        raise ParameterError(
            f"option(s) {', '.join(bad)} do not apply to control {name!r}; it takes {', '.join(allowed)}."
        )
    return CONTROLS[name][0](motor, **options)
