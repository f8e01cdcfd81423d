"""Synthetic drive logs for testing identification: the closed-loop simulator plus measurement noise.

The log records what a drive's firmware would: at each control period start ``t_k`` the sampled dq
currents, mechanical speed and electrical angle, and the dq voltage applied over the period that
starts there. With the averaged bridge the applied voltage is the period-average inverter voltage
(the commanded voltage one period late, because of the computational delay), held in the stator frame;
it is logged in dq with the angle at ``t_k``, so ``inverse_park(u_dq[k], theta_e[k])`` is exactly the
held stator voltage (``hold="stator"`` in :mod:`pmsmjax.studies.replay`).

``hold="rotor"`` imitates another simulator (a dq-model block fed by a sampled controller): its bridge
holds the period voltage constant in the rotor frame, and the log holds that dq voltage.

Noise: white Gaussian, standard deviation = level x RMS of the vector magnitude over the log (the same
for both axes), on the currents and on the voltages; speed and angle are logged noise-free (an encoder
with a good speed estimate).
"""

import equinox as eqx
import numpy as np

from pmsmjax.frames.three_phase import abc_to_alpha_beta, park
from pmsmjax.inverters.averaged import AveragedBridge, phase_voltages
from pmsmjax.machines.base import MachineInput
from pmsmjax.machines.integrate import advance
from pmsmjax.machines.motor import PMSMParameters
from pmsmjax.presets.three_phase import book_drive
from pmsmjax.scenarios import Scenario
from pmsmjax.simulate import simulate

__all__ = ["ID_TEST_MOTOR", "RotorHoldBridge", "simulate_log", "add_noise"]

#: The motor of the identification tests: different from every preset (book: R 0.958, L 5.25 mH,
#: psi_f 0.1827, J 0.003, B 0.008) and salient (L_q/L_d = 1.54) so that L_d and L_q are separable.
ID_TEST_MOTOR = dict(R=1.31, L_d=4.1e-3, L_q=6.3e-3, psi_f=0.153, J=0.0047, B=0.0052, pole_pairs=4)


class RotorHoldBridge(AveragedBridge):
    """Averaged bridge whose period voltage is held in the rotor frame (another simulator's convention).

    The period-average stator voltage is turned into dq with the angle at the period start and held
    there, so the stator-frame voltage rotates with the rotor during the period.
    """

    def advance(self, machine, state, duties, load_torque, Ts, n_substeps):
        u_ab = abc_to_alpha_beta(phase_voltages(duties, self.u_dc))
        u_dq = park(u_ab, state.theta_e)
        new_state = advance(machine, state, MachineInput(u_dq, load_torque, "rotor"), Ts, n_substeps)
        return new_state, u_ab


def simulate_log(
    scenario: Scenario,
    motor: PMSMParameters | None = None,
    *,
    hold: str = "stator",
    n_substeps: int = 10,
    id_zero: bool = False,
) -> dict[str, np.ndarray]:
    """Noise-free log of the book drive (its design-rule gains for ``motor``) running ``scenario``.

    Returns ``(N,)`` float64 columns ``time, u_d, u_q, i_d, i_q, omega_m, theta_e, T_L``; ``hold``:
    ``"stator"`` (our averaged inverter) or ``"rotor"`` (:class:`RotorHoldBridge`). ``id_zero``: no
    d-axis injection (the scenario's ``id_ref`` replaced by 0).
    """
    motor = PMSMParameters(**ID_TEST_MOTOR) if motor is None else motor
    drive = book_drive(motor, n_substeps=n_substeps)
    if hold == "rotor":
        drive = _replace_bridge(drive, RotorHoldBridge(drive.bridge.u_dc))
    elif hold != "stator":
        raise ValueError(f"hold must be 'stator' or 'rotor', got {hold!r}")
    if id_zero:
        scenario = Scenario(scenario.duration_s, scenario.speed_ref, scenario.load_torque)
    tr = simulate(drive, scenario)
    u_ab = abc_to_alpha_beta(tr.u_abc)
    u_dq = np.asarray(park(u_ab, tr.theta_e))
    cols = {
        "time": tr.t,
        "u_d": u_dq[:, 0],
        "u_q": u_dq[:, 1],
        "i_d": tr.i_dq[:, 0],
        "i_q": tr.i_dq[:, 1],
        "omega_m": tr.omega_m,
        "theta_e": tr.theta_e,
        "T_L": tr.load_torque,
    }
    return {k: np.asarray(v, dtype=np.float64) for k, v in cols.items()}


def add_noise(
    log: dict[str, np.ndarray], current: float = 0.01, voltage: float = 0.005, seed: int = 0
) -> dict[str, np.ndarray]:
    """A copy of ``log`` with white noise on ``i_d, i_q`` and ``u_d, u_q`` (levels relative to RMS)."""
    rng = np.random.default_rng(seed)
    out = dict(log)
    for (a, b), level in ((("i_d", "i_q"), current), (("u_d", "u_q"), voltage)):
        sigma = level * float(np.sqrt(np.mean(log[a] ** 2 + log[b] ** 2)))
        out[a] = log[a] + sigma * rng.standard_normal(log[a].shape)
        out[b] = log[b] + sigma * rng.standard_normal(log[b].shape)
    return out


def _replace_bridge(drive, bridge):
    return eqx.tree_at(lambda d: d.bridge, drive, bridge)
