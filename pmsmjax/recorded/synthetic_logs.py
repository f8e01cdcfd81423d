"""Drive logs made by this project's own drive, with measurement noise: what the chapter 5 observers are
tested, benchmarked and tuned on (``pmsmjax observe`` reads the stator-frame layout from files) and what
parameter identification ([`tuning.identify`][tuning.identify], ``pmsmjax identify``) is tested on (the dq
layout).

A log records what a drive's firmware would, per control period ``t_k``: the voltage applied over
``[t_k, t_{k+1})`` (the period average of the applied duties, which the averaged bridge applies exactly:
the commanded voltage one period late, because of the computational delay) and the currents sampled at
``t_k``, plus the true electrical angle and mechanical speed (``theta_e``, ``omega_m``; in the dq layout
also the load torque ``T_L``), see [`LOG_COLUMNS`][pmsmjax.recorded.synthetic_logs.LOG_COLUMNS]. In the dq
layout the stator voltage is turned into dq with the angle at ``t_k``, so
``inverse_park(u_dq[k], theta_e[k])`` is exactly the held stator voltage (``hold="stator"`` in
[`pmsmjax.recorded.replay`][pmsmjax.recorded.replay]).

Noise ([`add_measurement_noise`][pmsmjax.recorded.synthetic_logs.add_measurement_noise]): white Gaussian,
standard deviation ``level`` times the RMS of the vector's magnitude over the log, the same on both axes,
drawn independently on the voltages and on the currents; speed, angle and load stay noise-free (an encoder
with a good speed estimate).

The identification log ([`identification_log`][pmsmjax.recorded.synthetic_logs.identification_log]) is the
book drive's closed loop on [`ID_TEST_MOTOR`][pmsmjax.recorded.synthetic_logs.ID_TEST_MOTOR]; ``hold="rotor"``
imitates another simulator ([`RotorHoldBridge`][pmsmjax.recorded.synthetic_logs.RotorHoldBridge]).
"""

from collections.abc import Mapping

import equinox as eqx
import numpy as np

from pmsmjax._types import Array
from pmsmjax.assemble import with_parts
from pmsmjax.drive import Drive
from pmsmjax.frames.three_phase import abc_to_alpha_beta, park
from pmsmjax.inverters.averaged import phase_voltages
from pmsmjax.inverters.base import AbstractBridge
from pmsmjax.machines.base import MachineInput
from pmsmjax.machines.integrate import advance
from pmsmjax.machines.motor import PMSMParameters, as_float
from pmsmjax.presets.three_phase import book_drive
from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.simulate import simulate
from pmsmjax.spec.validation import check_positive
from pmsmjax.units import rpm_to_rad_s

__all__ = [
    "ID_LOG_NOISE",
    "ID_TEST_MOTOR",
    "LOG_COLUMNS",
    "RotorHoldBridge",
    "add_measurement_noise",
    "drive_log",
    "identification_log",
    "speed_scenario",
]

#: The columns of a log by frame: time, voltage pair, current pair, then the noise-free truth.
LOG_COLUMNS = {
    "alpha_beta": ("time", "u_alpha", "u_beta", "i_alpha", "i_beta", "theta_e", "omega_m"),
    "dq": ("time", "u_d", "u_q", "i_d", "i_q", "omega_m", "theta_e", "T_L"),
}

#: The motor of the identification tests: different from every preset
#: ([`pmsmjax.presets.book_constants`][pmsmjax.presets.book_constants]) and salient (L_q/L_d = 1.54) so that
#: L_d and L_q are separable. SI units: ohm, H, H, Wb, kg m^2, N m s/rad, pole pairs.
ID_TEST_MOTOR = dict(R=1.31, L_d=4.1e-3, L_q=6.3e-3, psi_f=0.153, J=0.0047, B=0.0052, pole_pairs=4)

#: The noise of the identification logs, in the order drawn: 1 % on the dq currents, 0.5 % on the dq
#: voltages (relative to each vector's RMS magnitude).
ID_LOG_NOISE = {("i_d", "i_q"): 0.01, ("u_d", "u_q"): 0.005}


def speed_scenario(
    speed_rpm: float, duration_s: float = 0.3, load_nm: float = 10.0, load_time_s: float = 0.15
) -> Scenario:
    """Speed step from rest to ``speed_rpm`` at t = 0, load step 0 -> ``load_nm`` at ``load_time_s``."""
    return Scenario(
        duration_s=duration_s,
        speed_ref=Profile.constant(rpm_to_rad_s(speed_rpm)),
        load_torque=Profile.step(load_time_s, 0.0, load_nm),
    )


def drive_log(
    drive: Drive,
    scenario: Scenario,
    *,
    frame: str = "alpha_beta",
    noise: float | Mapping = 0.0,
    seed: int = 0,
) -> dict[str, np.ndarray]:
    """Simulate ``drive`` (its estimator in the loop; the exact sensor for the book drive) through
    ``scenario`` and return its log.

    **Arguments:**

    - `frame`: ``"alpha_beta"`` (stator frame) or ``"dq"`` (rotor frame, angle at the period start); the
      columns are [`LOG_COLUMNS`][pmsmjax.recorded.synthetic_logs.LOG_COLUMNS] ``[frame]``, each ``(N,)``
      float64 (s, V, A, rad, rad/s, N m).
    - `noise`, `seed`: measurement noise as
      [`add_measurement_noise`][pmsmjax.recorded.synthetic_logs.add_measurement_noise] takes it (0: none).
    """
    if frame not in LOG_COLUMNS:
        raise ValueError(f"frame must be one of {sorted(LOG_COLUMNS)}, got {frame!r}")
    tr = simulate(drive, scenario)
    u_ab = abc_to_alpha_beta(tr.u_abc)
    if frame == "alpha_beta":
        u, i = u_ab, abc_to_alpha_beta(tr.i_abc)
    else:
        u, i = park(u_ab, tr.theta_e), tr.i_dq
    u, i = np.asarray(u, dtype=np.float64), np.asarray(i, dtype=np.float64)
    time, u_x, u_y, i_x, i_y, *truth = LOG_COLUMNS[frame]
    recorded = {"theta_e": tr.theta_e, "omega_m": tr.omega_m, "T_L": tr.load_torque}
    log = {time: np.asarray(tr.t, dtype=np.float64), u_x: u[:, 0], u_y: u[:, 1], i_x: i[:, 0], i_y: i[:, 1]}
    log.update({name: np.asarray(recorded[name], dtype=np.float64) for name in truth})
    if isinstance(noise, Mapping) or noise > 0:
        log = add_measurement_noise(log, noise, seed)
    return log


def add_measurement_noise(
    log: dict[str, np.ndarray], level: float | Mapping[tuple[str, str], float], seed: int = 0
) -> dict[str, np.ndarray]:
    """A copy of ``log`` with white noise on its voltage and current pairs (module docstring).

    **Arguments:**

    - `level`: one relative level for the voltage pair and then the current pair of the log's frame
      (drawn in that order), or ``{(column_a, column_b): level}`` drawn in the mapping's order (e.g.
      [`ID_LOG_NOISE`][pmsmjax.recorded.synthetic_logs.ID_LOG_NOISE]).
    - `seed`: the generator's seed; the same seed, levels and order give the same draws.
    """
    if not isinstance(level, Mapping):
        frame = "alpha_beta" if "u_alpha" in log else "dq"
        u_x, u_y, i_x, i_y = LOG_COLUMNS[frame][1:5]
        level = {(u_x, u_y): level, (i_x, i_y): level}
    rng = np.random.default_rng(seed)
    out = dict(log)
    for (a, b), pair_level in level.items():
        sigma = pair_level * float(np.sqrt(np.mean(log[a] ** 2 + log[b] ** 2)))
        out[a] = log[a] + sigma * rng.standard_normal(log[a].shape)
        out[b] = log[b] + sigma * rng.standard_normal(log[b].shape)
    return out


class RotorHoldBridge(AbstractBridge):
    """Ideal averaged bridge whose period voltage is held in the rotor frame (another simulator's
    convention: a dq-model block fed by a sampled controller).

    The period-average stator voltage
    ([`pmsmjax.inverters.averaged.phase_voltages`][pmsmjax.inverters.averaged.phase_voltages], as the ideal
    [`AveragedBridge`][pmsmjax.inverters.averaged.AveragedBridge]) is turned into dq with the angle at the
    period start and held there, so the stator-frame voltage rotates with the rotor during the period.

    **Arguments:** `u_dc`: DC-link voltage, V.
    """

    u_dc: Array = eqx.field(converter=as_float)

    def __check_init__(self):
        check_positive("u_dc (DC-link voltage)", self.u_dc, "V")

    def advance(self, machine, state, duties, load_torque, Ts, n_substeps):
        u_ab = abc_to_alpha_beta(phase_voltages(duties, self.u_dc))
        u_dq = park(u_ab, state.theta_e)
        new_state = advance(machine, state, MachineInput(u_dq, load_torque, "rotor"), Ts, n_substeps)
        return new_state, u_ab


def identification_log(
    scenario: Scenario,
    motor: PMSMParameters | None = None,
    *,
    hold: str = "stator",
    n_substeps: int = 10,
    id_zero: bool = False,
) -> dict[str, np.ndarray]:
    """Noise-free dq log ([`LOG_COLUMNS`][pmsmjax.recorded.synthetic_logs.LOG_COLUMNS] ``["dq"]``) of the book
    drive, its design-rule gains for ``motor`` (default
    [`ID_TEST_MOTOR`][pmsmjax.recorded.synthetic_logs.ID_TEST_MOTOR]), running ``scenario``.

    ``hold``: ``"stator"`` (this project's averaged bridge) or ``"rotor"``
    ([`RotorHoldBridge`][pmsmjax.recorded.synthetic_logs.RotorHoldBridge]). ``id_zero``: no d-axis injection
    (the scenario's ``id_ref`` replaced by 0).
    """
    motor = PMSMParameters(**ID_TEST_MOTOR) if motor is None else motor
    drive = book_drive(motor, n_substeps=n_substeps)
    if hold == "rotor":
        drive = with_parts(drive, {"bridge": RotorHoldBridge(drive.bridge.u_dc)})
    elif hold != "stator":
        raise ValueError(f"hold must be 'stator' or 'rotor', got {hold!r}")
    if id_zero:
        scenario = Scenario(scenario.duration_s, scenario.speed_ref, scenario.load_torque)
    return drive_log(drive, scenario, frame="dq")
