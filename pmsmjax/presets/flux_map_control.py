"""Control on a flux map: a drive whose plant is a saturated machine's map gets the map's current loop and
d-axis references ([`pmsmjax.controllers.flux_map_current_loop`][pmsmjax.controllers.flux_map_current_loop],
[`pmsmjax.controllers.flux_map_references`][pmsmjax.controllers.flux_map_references]).

- The dq PI current loop becomes
  [`FluxMapCurrentLoop`][pmsmjax.controllers.flux_map_current_loop.FluxMapCurrentLoop] with the same bandwidth
  (read back from the internal-model gains, ``a_c = kp_d / L_d``, so an override of the preset's
  ``current_bandwidth`` carries over).
- That cascade (a FOC: the ``pi`` and ``smc`` controls) gets field weakening on the map's MTPA and
  MTPV tables ([`FluxMapFieldWeakening`][pmsmjax.controllers.flux_map_references.FluxMapFieldWeakening]), with
  the voltage loop at [`field_weakening_block`][pmsmjax.presets.three_phase.field_weakening_block]'s bandwidth
  and margin: MTPA below base speed, the voltage limit above it. In current mode (``mode="current"``) the
  scenario's ``i_d*`` stands: no d-axis reference is installed over it.

The other controls (proportional-resonant and hysteresis current control, direct torque control) are
kept as they are: on the map's plant, with their linear-model design.
"""

import equinox as eqx

from pmsmjax.drive import Drive
from pmsmjax.machines.flux_map import FluxMapGrid

__all__ = ["with_flux_map_control"]


def with_flux_map_control(drive: Drive, grid: FluxMapGrid) -> Drive:
    """``drive`` (its plant the map ``grid``'s) with the map's current loop and d-axis references
    (module docstring); the tables cover the controller's current limit."""
    from pmsmjax.controllers.current_pi import CurrentLoopGains
    from pmsmjax.controllers.flux_map_current_loop import FluxMapCurrentLoop
    from pmsmjax.controllers.flux_map_references import flux_map_field_weakening
    from pmsmjax.machines.pmsm_flux_map import FluxMap
    from pmsmjax.presets.three_phase import field_weakening_block

    c = drive.controller
    current = getattr(c, "current", None)
    if not isinstance(current, CurrentLoopGains):
        return drive
    a_c = float(current.kp_d / c.model.L_d)
    loop = FluxMapCurrentLoop.imc(FluxMap.from_grid(grid), c.model, a_c)
    drive = eqx.tree_at(lambda d: d.controller.current, drive, loop)
    # In current mode the scenario gives i_d* (and i_q*): no MTPA or field-weakening reference over it.
    if hasattr(c, "d_axis") and getattr(c, "mode", "speed") == "speed":
        rule = field_weakening_block(a_c)
        fw = flux_map_field_weakening(
            grid, int(c.model.pole_pairs), float(c.current_limit), float(rule.bandwidth),
            float(rule.voltage_margin),
        )  # fmt: skip
        drive = eqx.tree_at(lambda d: d.controller.d_axis, drive, fw, is_leaf=lambda x: x is None)
    return drive
