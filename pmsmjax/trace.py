"""The simulation result: every signal an engineer plots, one row per recorded control period."""

import equinox as eqx
import numpy as np

from pmsmjax._types import Array
from pmsmjax.units import CELSIUS_K, rad_s_to_rpm

# Column name -> (Trace attribute, index into the last axis or None), for CSV/NPZ export.
_COLUMNS = {
    "time": ("t", None),
    "omega_m": ("omega_m", None),
    "speed_rpm": ("speed_rpm", None),
    "speed_ref": ("speed_ref", None),
    "speed_ref_rpm": ("speed_ref_rpm", None),
    "theta_e": ("theta_e", None),
    "i_d": ("i_dq", 0),
    "i_q": ("i_dq", 1),
    "i_d_ref": ("i_dq_ref", 0),
    "i_q_ref": ("i_dq_ref", 1),
    "i_a": ("i_abc", 0),
    "i_b": ("i_abc", 1),
    "i_c": ("i_abc", 2),
    "u_d_ref": ("u_dq_ref", 0),
    "u_q_ref": ("u_dq_ref", 1),
    "u_a": ("u_abc", 0),
    "u_b": ("u_abc", 1),
    "u_c": ("u_abc", 2),
    "duty_a": ("duties", 0),
    "duty_b": ("duties", 1),
    "duty_c": ("duties", 2),
    "torque": ("torque", None),
    "load_torque": ("load_torque", None),
    "theta_e_est": ("theta_e_est", None),
    "omega_m_est": ("omega_m_est", None),
}

#: Unit of every exported column: speeds come in both rad/s (``omega_m``, ``speed_ref``, mechanical) and
#: r/min (``speed_rpm``, ``speed_ref_rpm``); ``pmsmjax demo`` writes this table into summary.json.
COLUMN_UNITS = {
    "time": "s (period start)",
    "omega_m": "rad/s (mechanical speed)",
    "speed_rpm": "r/min (mechanical speed)",
    "speed_ref": "rad/s (speed reference, mechanical)",
    "speed_ref_rpm": "r/min (speed reference)",
    "theta_e": "rad (electrical angle)",
    "i_d": "A",
    "i_q": "A",
    "i_d_ref": "A",
    "i_q_ref": "A",
    "i_a": "A",
    "i_b": "A",
    "i_c": "A",
    "u_d_ref": "V (controller's dq voltage command)",
    "u_q_ref": "V (controller's dq voltage command)",
    "u_a": "V (period-average phase voltage applied)",
    "u_b": "V (period-average phase voltage applied)",
    "u_c": "V (period-average phase voltage applied)",
    "duty_a": "1 (leg duty cycle applied)",
    "duty_b": "1 (leg duty cycle applied)",
    "duty_c": "1 (leg duty cycle applied)",
    "torque": "N m (electromagnetic)",
    "load_torque": "N m",
    "theta_e_est": "rad (estimator's electrical angle)",
    "omega_m_est": "rad/s (estimator's mechanical speed)",
}

#: The further column of a warm motor's trace (a drive with a thermal network,
#: [`pmsmjax.machines.thermal`][pmsmjax.machines.thermal]).
THERMAL_COLUMN_UNITS = {"winding_temperature_c": "degC (winding temperature at the period start)"}

#: The further column of a drive with a compliant shaft ([`pmsmjax.machines.shaft`][pmsmjax.machines.shaft]).
SHAFT_COLUMN_UNITS = {"load_speed": "rad/s (load-side mechanical speed)"}
#: The further column of a drive with cogging torque (``[harmonics] cogging``,
#: [`pmsmjax.machines.harmonics`][pmsmjax.machines.harmonics]); the ``torque`` column includes it.
COGGING_COLUMN_UNITS = {"cogging_torque": "N m (cogging torque at the period start, included in torque)"}

#: The further columns of a six-phase trace (the second set U, V, W;
#: [`Trace.columns`][pmsmjax.trace.Trace.columns]).
SIX_PHASE_COLUMN_UNITS = {
    **{f"i_{x}": "A" for x in "uvw"},
    **{f"u_{x}": "V (period-average phase voltage applied)" for x in "uvw"},
    **{f"duty_{x}": "1 (leg duty cycle applied)" for x in "uvw"},
}

#: The further columns of a five-phase trace (phases D and E, capitals: ``i_d`` is the d-axis current).
FIVE_PHASE_COLUMN_UNITS = {
    **{f"i_{x}": "A (phase current)" for x in "DE"},
    **{f"u_{x}": "V (period-average phase voltage applied)" for x in "DE"},
    **{f"duty_{x}": "1 (leg duty cycle applied)" for x in "DE"},
}


class Trace(eqx.Module):
    """Recorded signals; the leading axis is time (after any batch axes from ``vmap``).

    ``N`` is the number of recorded periods, ``n`` the phase count (3; six phases: A, B, C, U, V, W).

    Attributes:
        t: ``(N,)`` period start times, s.
        omega_m: Mechanical speed, rad/s.
        speed_ref: Speed reference, rad/s.
        theta_e: Electrical angle, rad.
        i_dq: ``(N, 2)`` measured dq currents, A.
        i_dq_ref: ``(N, 2)`` reference dq currents, A.
        i_abc: ``(N, n)`` phase currents, A.
        u_dq_ref: ``(N, 2)`` controller voltage command, V.
        u_abc: ``(N, n)`` period-average applied phase voltages, V.
        duties: ``(N, n)`` applied leg duty cycles.
        torque: Electromagnetic torque, N m.
        load_torque: Load torque, N m.
        theta_e_est: The estimator's electrical angle that the controller used, rad (equal to ``theta_e``
            with the exact sensor).
        omega_m_est: The estimator's mechanical speed that the controller used, rad/s (equal to
            ``omega_m`` with the exact sensor).
        winding_temperature: Winding temperature at the period start, K; ``None`` without a thermal
            network (exported as ``winding_temperature_c``, degC).
        load_speed: Load-side mechanical speed at the period start, rad/s; ``None`` for a rigid shaft
            (``omega_m`` is then the load's speed too).
        cogging_torque: Cogging torque at the period start, N m (part of ``torque``); ``None`` without
            cogging.
    """

    t: Array
    omega_m: Array
    speed_ref: Array
    theta_e: Array
    i_dq: Array
    i_dq_ref: Array
    i_abc: Array
    u_dq_ref: Array
    u_abc: Array
    duties: Array
    torque: Array
    load_torque: Array
    theta_e_est: Array
    omega_m_est: Array
    winding_temperature: Array | None = None
    load_speed: Array | None = None
    cogging_torque: Array | None = None

    @property
    def speed_rpm(self) -> Array:
        """Mechanical speed, r/min (``omega_m`` converted)."""
        return rad_s_to_rpm(self.omega_m)

    @property
    def speed_ref_rpm(self) -> Array:
        """Speed reference, r/min (``speed_ref`` converted)."""
        return rad_s_to_rpm(self.speed_ref)

    def columns(self) -> dict[str, np.ndarray]:
        """Flat named columns (NumPy) for a single (unbatched) trace.

        Returns:
            Column name -> ``(N,)`` array (the names of the trace files, one column per phase and axis).

        Raises:
            ValueError: For a batched trace (index the batch first, e.g. ``trace[i]``).
        """
        if np.ndim(self.t) != 1:
            raise ValueError("columns() needs a single trace; index the batch first, e.g. trace[i].")
        out = {}
        for name, (attr, idx) in _COLUMNS.items():
            x = np.asarray(getattr(self, attr))
            out[name] = x if idx is None else x[..., idx]
        if np.shape(self.i_abc)[-1] == 6:  # the second set of a six-phase machine
            for k, phase in enumerate("uvw", start=3):
                out[f"i_{phase}"] = np.asarray(self.i_abc)[..., k]
                out[f"u_{phase}"] = np.asarray(self.u_abc)[..., k]
                out[f"duty_{phase}"] = np.asarray(self.duties)[..., k]
        elif np.shape(self.i_abc)[-1] == 5:  # phases D and E of a five-phase machine
            for k, phase in enumerate("DE", start=3):
                out[f"i_{phase}"] = np.asarray(self.i_abc)[..., k]
                out[f"u_{phase}"] = np.asarray(self.u_abc)[..., k]
                out[f"duty_{phase}"] = np.asarray(self.duties)[..., k]
        if self.winding_temperature is not None:
            out["winding_temperature_c"] = np.asarray(self.winding_temperature) - CELSIUS_K
        if self.load_speed is not None:
            out["load_speed"] = np.asarray(self.load_speed)
        if self.cogging_torque is not None:
            out["cogging_torque"] = np.asarray(self.cogging_torque)
        return out

    def to_numpy(self) -> "Trace":
        """The same trace with NumPy leaves.

        Figures of merit, plots and files computed from it are then plain NumPy
        ([`pmsmjax.analysis.metrics`][pmsmjax.analysis.metrics] dispatches on the array type), so
        post-processing a run compiles nothing. Waits for the simulation to finish.
        """
        import jax

        return jax.tree.map(np.asarray, self)

    def __getitem__(self, index) -> "Trace":
        """Select along the leading (batch) axis."""
        import jax

        return jax.tree.map(lambda x: x[index], self)
