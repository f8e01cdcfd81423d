"""The hybrid estimator's two reference runs, shared by tests/estimators/test_hybrid.py and
benchmarks/hybrid_table.py: the book drive on the salient book motor with d-axis saturation
([`pmsmjax.machines.saturated_machine`][pmsmjax.machines.saturation.saturated_machine]), sensorless with
[`pmsmjax.estimators.hybrid.hybrid_design`][pmsmjax.estimators.hybrid.hybrid_design] from standstill at
several initial rotor angles.

- ``book``: the book scenario (1000 r/min step at t = 0, 10 N m load step at 0.2 s, 0.4 s);
- ``reversal``: -1000 r/min from standstill, 5 N m load from 0.15 s, speed step to +1000 r/min at 0.3 s,
  0.7 s in all (the load is applied after the start so that the standstill polarity pulses are not made
  against an active load torque that would turn the rotor).
"""

import jax
import jax.numpy as jnp
import numpy as np

from pmsmjax.analysis.observer_errors import LOCK_ANGLE_RAD, angle_error, rms_and_max_abs
from pmsmjax.assemble import with_parts
from pmsmjax.machines.saturation import saturated_machine
from pmsmjax.presets.three_phase import book_drive, book_motor, book_scenario
from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.simulate import simulate
from pmsmjax.units import rad_s_to_rpm, rpm_to_rad_s

#: Start-up is over (polarity pulses, hand-over) by this time, s; errors are judged after it.
STARTUP_S = 0.06


def hybrid_book_drive(**hybrid_options):
    """The book drive (salient, saturating machine) with the hybrid estimator (options: its design rule's)."""
    from pmsmjax.estimators.hybrid import hybrid_design

    motor = book_motor(salient=True)
    drive = book_drive(motor)
    estimator = hybrid_design(motor, drive.Ts, **hybrid_options)
    return with_parts(drive, {"machine": saturated_machine(motor), "estimator": estimator})


def hybrid_scenarios() -> dict:
    """``{"book": Scenario, "reversal": Scenario}`` (module docstring)."""
    w = rpm_to_rad_s(1000.0)
    reversal = Scenario(
        duration_s=0.7, speed_ref=Profile.step(0.3, -w, w), load_torque=Profile.step(0.15, 0.0, 5.0)
    )
    return {"book": book_scenario(), "reversal": reversal}


def run_from_angles(drive, scenario, angles) -> dict:
    """Simulate ``drive`` from standstill at each initial electrical angle in ``angles`` (rad), batched;
    NumPy arrays ``t (K,)``, ``omega_m``, ``omega_m_est``, ``speed_ref``, ``angle_error`` (rad, wrapped),
    ``(len(angles), K)``."""

    def run(theta0):
        tr = simulate(drive, scenario, initial_state=drive.init(theta_e=theta0))
        return tr.t, tr.omega_m, tr.omega_m_est, tr.speed_ref, angle_error(tr.theta_e_est, tr.theta_e)

    t, w, w_est, ref, err = jax.jit(jax.vmap(run))(jnp.asarray(angles))
    return dict(
        t=np.asarray(t[0]),
        omega_m=np.asarray(w),
        omega_m_est=np.asarray(w_est),
        speed_ref=np.asarray(ref),
        angle_error=np.asarray(err),
    )


def summary(result: dict) -> dict:
    """Per initial angle: max and RMS angle error after start-up (electrical degrees), final speed error
    (r/min, plant minus reference), and whether lock held: no period out of lock by angle
    ([`pmsmjax.analysis.observer_errors.LOCK_ANGLE_RAD`][pmsmjax.analysis.observer_errors.LOCK_ANGLE_RAD], 90
    degrees; a slip by a pole would show as 180)."""
    after = result["t"] >= STARTUP_S
    err = result["angle_error"][:, after]
    rms, largest = rms_and_max_abs(err, axis=1)
    final = rad_s_to_rpm(result["omega_m"][:, -1] - result["speed_ref"][:, -1])
    return dict(
        max_deg=np.degrees(largest),
        rms_deg=np.degrees(rms),
        final_speed_error_rpm=final,
        locked=largest < LOCK_ANGLE_RAD,
    )
