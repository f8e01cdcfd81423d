"""Gradient of a hybrid-estimator objective w.r.t. its crossover band against central differences.

Objective: mean-square angle error (rad^2) from 50 to 100 ms of a start from standstill to 1000 r/min
([`pmsmjax.jobs.hybrid_runs.hybrid_book_drive`][pmsmjax.jobs.hybrid_runs.hybrid_book_drive], rotor at 0.3
rad), i.e. through the polarity pulses, the hand-over and the carrier fade. ``jax.grad`` w.r.t.
``(low_speed, high_speed)`` (mechanical rad/s) against central differences with steps 1e-3 and 1e-4 rad/s,
float64. Not a test: the reverse-mode compile of the two estimators' scan takes about 30 s on 2 CPU cores,
over the test budget.

    python -m benchmarks.hybrid_gradient
"""

import jax
import jax.numpy as jnp
import numpy as np


def main():
    jax.config.update("jax_enable_x64", True)
    import equinox as eqx

    from pmsmjax.analysis.observer_errors import angle_error
    from pmsmjax.jobs.hybrid_runs import hybrid_book_drive
    from pmsmjax.scenarios import Profile, Scenario
    from pmsmjax.simulate import simulate

    drive = hybrid_book_drive()
    sc = Scenario(duration_s=0.1, speed_ref=Profile.constant(104.7), load_torque=Profile.constant(0.0))

    def loss(p):
        d = eqx.tree_at(lambda d: (d.estimator.low_speed, d.estimator.high_speed), drive, (p[0], p[1]))
        tr = simulate(d, sc, initial_state=d.init(theta_e=0.3))
        e = angle_error(tr.theta_e_est, tr.theta_e)
        return jnp.mean(jnp.where(tr.t > 0.05, e, 0.0) ** 2)

    p0 = jnp.array([float(drive.estimator.low_speed), float(drive.estimator.high_speed)])
    g = np.asarray(jax.jit(jax.grad(loss))(p0))
    value = jax.jit(loss)
    print(f"objective {float(value(p0)):.6e} rad^2; grad (low, high) {g}")
    for h in (1e-3, 1e-4):
        fd = np.array([(value(p0.at[i].add(h)) - value(p0.at[i].add(-h))) / (2 * h) for i in range(2)])
        rel = np.max(np.abs(fd - g) / np.abs(g))
        print(f"central differences h = {h:g}: {fd}; max relative difference {rel:.1e}")


if __name__ == "__main__":
    main()
