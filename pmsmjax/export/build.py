"""The drive ``pmsmjax export`` writes, built as ``pmsmjax demo`` builds it: the control method's preset on
the drive file ([`pmsmjax.assemble.assemble`][pmsmjax.assemble.assemble]), MTPA and voltage-feedback field
weakening when asked for ([`field_weakening_block`][pmsmjax.presets.three_phase.field_weakening_block] at the
file's current-loop bandwidth), then the caller's adjustment (the gains of a gains file)."""

from collections.abc import Callable

__all__ = ["export_drive"]


def export_drive(spec, control: str = "pi", field_weakening: bool = False, adjust: Callable | None = None):
    """The three-phase drive of ``control`` on the drive file ``spec``
    ([`DriveSpec`][pmsmjax.spec.drive_spec.DriveSpec]).

    Args:
        spec: the checked drive file.
        control: the control method (the registry's name).
        field_weakening: add MTPA and voltage-feedback field weakening (``pmsmjax demo --field-weakening``).
        adjust: ``(drive, control) -> drive`` applied last (tuned gains), or None.

    Returns:
        The [`Drive`][pmsmjax.drive.Drive].
    """
    from pmsmjax.assemble import assemble

    options = {}
    if field_weakening:
        from pmsmjax.presets import field_weakening_block

        options["d_axis"] = field_weakening_block(spec.control["current_bandwidth_rad_s"])
    drive = assemble(spec, control, options=options)
    return drive if adjust is None else adjust(drive, control)
