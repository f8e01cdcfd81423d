"""Control methods by name: the three-phase controls of `pmsmjax.spec.registry.REGISTRY` with the
presets that build their drives, behind ``pmsmjax demo --control``, ``pmsmjax compare`` and
``pmsmjax tune --control``. A method added to the registry is known to every command.
"""

from pmsmjax.drive import Drive
from pmsmjax.machines.motor import PMSMParameters
from pmsmjax.spec import registry

#: Control name -> (preset building its drive, one-line description).
CONTROLS = {
    name: (registry.load_factory(entry := registry.method("control", name)), entry.description)
    for name in registry.names("control", "three-phase")
}


def control_options(name: str) -> tuple[str, ...]:
    """Keyword options the preset of control ``name`` accepts (declared in the registry)."""
    return registry.method("control", name, what="control").options


def control_drive(name: str, motor: PMSMParameters | None = None, **options) -> Drive:
    """The drive of control ``name`` on ``motor`` (default the book motor), with preset ``options``.

    An option the preset does not take is refused with the list of those it does.
    """
    entry = registry.method("control", name, what="control")
    registry.check_options(entry, options)
    return CONTROLS[name][0](motor, **options)
