"""An anticogging table loaded into a drive (``pmsmjax demo --anticogging FILE``): the q currents that
``pmsmjax tune --anticogging`` wrote ([`pmsmjax.io.anticogging_files`][pmsmjax.io.anticogging_files]) as the
FOC's [`AnticoggingTable`][pmsmjax.controllers.anticogging.AnticoggingTable]."""

from pmsmjax.spec.validation import ParameterError

__all__ = ["with_anticogging"]


def with_anticogging(adjust, iq_a):
    """A drive adjustment ``(drive, control) -> drive``: ``adjust`` (or none), then the table ``iq_a``
    (``(N,)`` A over one electrical revolution) in the drive's FOC; refused in one line for a controller
    without one."""

    def apply(drive, control):
        from pmsmjax.assemble import with_parts
        from pmsmjax.controllers.anticogging import AnticoggingTable

        drive = adjust(drive, control) if adjust is not None else drive
        if not hasattr(drive.controller, "anticogging"):
            raise ParameterError(
                f"--anticogging feeds a q current forward in a field-oriented controller; --control "
                f"{control} has none: choose a FOC control (pi, ...) or drop --anticogging."
            )
        return with_parts(drive, {"controller.anticogging": AnticoggingTable(iq_a)})

    return apply
