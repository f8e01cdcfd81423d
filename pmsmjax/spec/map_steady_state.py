"""Steady operating points of a flux-map machine: whether a speed and load fit the voltage and current limits,
and the top speed, judged on the map itself (NumPy; no JAX).

[`pmsmjax.spec.steady_state`][pmsmjax.spec.steady_state] answers the same questions on the linear model
(``psi_f``, ``L_d``, ``L_q``); on a strongly saturated machine that model is far off (a PM-assisted
reluctance machine's incremental ``L_q`` falls tenfold over the current range), so a run on a map is judged on
the map's flux: in steady state ``u_d = R i_d - w_e psi_q(i)``, ``u_q = R i_q + w_e psi_d(i)`` and
``T = 1.5 p (psi_d(i) i_q - psi_q(i) i_d)`` (amplitude-invariant dq, peak values; the book, ch. 1, with the
map's flux in place of the linear one).

The search is exhaustive on a polar grid of currents inside the current limit (magnitudes ``0..I_max``,
angles over the half plane of the torque's sign): without field weakening the point of least current that
gives the torque (MTPA), with field weakening the point of least voltage among those that give it. The grid
resolves the current to ``I_max / (n_magnitudes - 1)`` and the angle to ``pi / (n_angles - 1)``, so a
verdict within about 1 % of a limit is approximate; it is used to explain a finished run, not to refuse one.
"""

import math

import numpy as np

from pmsmjax.machines import dq_equations as dq
from pmsmjax.spec.steady_state import top_speed_where

__all__ = ["MapSteadyState", "map_steady_state", "map_reachable", "map_top_speed_rpm"]

RPM = math.pi / 30.0


class MapSteadyState:
    """The map's steady currents, fluxes and torques on a polar grid inside ``current_limit_a``, evaluated
    once (the flux does not depend on the speed), then asked at any speed and load.

    Args:
        grid: A [`FluxMapGrid`][pmsmjax.machines.flux_map.FluxMapGrid].
        pole_pairs: ``p``.
        R: Phase resistance, ohm.
        B: Viscous friction, N m s/rad (the steady torque at speed ``w`` is ``load + B w``).
        current_limit_a: ``I_max``, A (peak).
        n_magnitudes: Current magnitudes of the grid.
        n_angles: Current angles of the grid over ``[0, pi]``: ``i_d = I cos(beta)``, ``|i_q| = I sin(beta)``.
    """

    def __init__(
        self,
        grid,
        pole_pairs: int,
        R: float,
        B: float,
        current_limit_a: float,
        n_magnitudes: int = 161,
        n_angles: int = 361,
    ):
        magnitude = np.linspace(0.0, current_limit_a, n_magnitudes)[:, None]
        angle = np.linspace(0.0, math.pi, n_angles)[None, :]
        i_d = (magnitude * np.cos(angle)).ravel()
        i_q = (magnitude * np.sin(angle)).ravel()
        self.i_d = np.concatenate([i_d, i_d])
        self.i_q = np.concatenate([i_q, -i_q])
        psi, _ = grid.flux(np.stack([self.i_d, self.i_q], -1))
        self.psi_d, self.psi_q = psi[:, 0], psi[:, 1]
        self.torque = dq.torque(dq.torque_factor(pole_pairs), self.i_d, self.i_q, self.psi_d, self.psi_q)
        self.current = np.hypot(self.i_d, self.i_q)
        self.pole_pairs, self.R, self.B = pole_pairs, R, B
        self.current_limit_a = current_limit_a
        self.grid = grid
        self.rings = (2, n_magnitudes, n_angles)  # (sign of i_q, magnitude, angle) of the flat arrays

    def flux(self, i_d, i_q) -> tuple[np.ndarray, np.ndarray]:
        """``(psi_d, psi_q)`` (Wb) of the map at the currents ``i_d``, ``i_q`` (A, arrays that broadcast)."""
        psi, _ = self.grid.flux(np.stack(np.broadcast_arrays(i_d, i_q), -1))
        return psi[..., 0], psi[..., 1]

    def voltage(self, speed_rpm: float) -> np.ndarray:
        """Steady voltage magnitude of every grid point at ``speed_rpm`` (r/min), V (peak)."""
        w_e = self.pole_pairs * speed_rpm * RPM
        return dq.voltage_magnitude(self.R, w_e, self.i_d, self.i_q, self.psi_d, self.psi_q, np)

    def point(self, speed_rpm: float, load_nm: float, field_weakening: bool) -> dict:
        """The grid point that holds ``load_nm`` (N m, plus friction) at ``speed_rpm``: of least current
        (MTPA) or, with ``field_weakening``, of least voltage. ``{"ok_current", "i_d", "i_q", "current",
        "voltage"}``; ``ok_current`` False when no point within the current limit gives the torque."""
        need = load_nm + self.B * speed_rpm * RPM
        gives = self.torque >= need if need >= 0 else self.torque <= need
        if not gives.any():
            return {"ok_current": False, "i_d": 0.0, "i_q": 0.0, "current": math.inf, "voltage": math.inf}
        volts = self.voltage(speed_rpm)
        if field_weakening:
            k = int(np.flatnonzero(gives)[np.argmin(volts[gives])])
        else:
            # MTPA: the smallest magnitude whose best angle gives the torque, at that angle
            block = 0 if need >= 0 else 1  # i_q >= 0 for motoring torque, <= 0 for generating
            signed = (self.torque if need >= 0 else -self.torque).reshape(self.rings)
            reach = signed.max(axis=-1) >= abs(need)  # (2, n_magnitudes)
            block = block if reach[block].any() else 1 - block
            ring = int(np.argmax(reach[block]))
            k = int(np.ravel_multi_index((block, ring, int(np.argmax(signed[block, ring]))), self.rings))
        return {
            "ok_current": True,
            "i_d": float(self.i_d[k]),
            "i_q": float(self.i_q[k]),
            "current": float(self.current[k]),
            "voltage": float(volts[k]),
        }


def map_steady_state(drive) -> MapSteadyState | None:
    """The [`MapSteadyState`][pmsmjax.spec.map_steady_state.MapSteadyState] of ``drive``'s flux-map machine
    at its current limit, or None for a machine without a map."""
    from pmsmjax.machines.flux_map import flux_and_inductance
    from pmsmjax.machines.pmsm_flux_map import PMSMFluxMapdq

    machine = drive.machine
    if not isinstance(machine, PMSMFluxMapdq):
        return None
    fm = machine.flux_map
    coefficients = np.asarray(fm.coefficients, dtype=float)
    lower, step = np.asarray(fm.lower, dtype=float), np.asarray(fm.step, dtype=float)
    upper = np.asarray(fm.upper, dtype=float)

    class _Interpolant:  # the plant's own interpolant, evaluated in NumPy
        @staticmethod
        def flux(i_dq):
            psi, L = flux_and_inductance(coefficients, lower, step, upper, i_dq, np)
            if machine.magnet_flux_offset is not None:
                psi = psi + np.array([float(np.asarray(machine.magnet_flux_offset)), 0.0])
            return psi, L

    m = machine.motor
    return MapSteadyState(
        _Interpolant,
        int(m.pole_pairs),
        float(np.max(np.asarray(m.R))),
        float(np.max(np.asarray(m.B))),
        float(np.min(np.asarray(drive.controller.current_limit))),
    )


def map_reachable(
    steady: MapSteadyState, speed_rpm: float, load_nm: float, u_limit_v: float, field_weakening: bool
) -> dict:
    """[`reachable`][pmsmjax.spec.steady_state.reachable] on the map: ``{"ok", "i_d", "current",
    "voltage", "limit"}``."""
    pt = steady.point(speed_rpm, load_nm, field_weakening)
    if not pt["ok_current"]:
        return {"ok": False, "i_d": pt["i_d"], "current": math.inf, "voltage": math.inf, "limit": "current"}
    ok = pt["voltage"] <= u_limit_v
    return {
        "ok": ok,
        "i_d": pt["i_d"],
        "current": pt["current"],
        "voltage": pt["voltage"],
        "limit": None if ok else "voltage",
    }


def map_top_speed_rpm(
    steady: MapSteadyState, u_limit_v: float, load_nm: float, field_weakening: bool, direction: float = 1.0
) -> float:
    """Largest speed (r/min, sign of ``direction``) at which ``load_nm`` is
    [`map_reachable`][pmsmjax.spec.map_steady_state.map_reachable]; 0 when not even at standstill."""
    sign = 1.0 if direction >= 0 else -1.0
    return top_speed_where(
        lambda n: map_reachable(steady, sign * n, load_nm, u_limit_v, field_weakening)["ok"], direction, 30
    )
