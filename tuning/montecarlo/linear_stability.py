"""Each Monte Carlo draw's drive linearised at its own final speed and load: is the closed loop stable?

A draw whose linearised sampled-data loop has an eigenvalue on or outside the unit circle (spectral radius of
``A`` >= 1, [`pmsmjax.analysis.loop_linearisation`][pmsmjax.analysis.loop_linearisation]) is flagged
``unstable_linearisation``: a small-signal instability at the operating point that a large-signal run may
hide (a limit cycle inside the current limit, a slowly growing resonance) or show only as a tracking failure.
The Jacobians are computed on the device in chunks (``vmap``), the eigenvalues on the host (NumPy).
"""

import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from pmsmjax.analysis.loop_linearisation import check_linearisable, linearise_traced

__all__ = ["check_nominal", "spectral_radii"]


def check_nominal(drive, study, apply_sample) -> None:
    """Refuse, in one line, a nominal drive or a final operating point outside the linearisation's scope
    ([`check_linearisable`][pmsmjax.analysis.loop_linearisation.check_linearisable]): called before the
    study runs, so that nothing is simulated or written for a check that cannot be made."""
    d0, s0 = apply_sample(drive, study, (), ())
    check_linearisable(
        d0, float(s0.speed_ref.values[-1]), float(s0.load_torque.values[-1]), where="the study's scenario"
    )


def spectral_radii(drive, study, names, values: np.ndarray, apply_sample, chunk: int = 256) -> tuple:
    """``((n,) spectral radii, seconds)`` of the ``n`` draws ``values (n, P)`` of ``names``.

    Args:
        drive: The study's nominal drive.
        study: The [`Study`][tuning.montecarlo.study.Study].
        names: The varied parameters' names.
        values: ``(n, P)`` the draws.
        apply_sample: ``(drive, study, names, row) -> (drive, scenario)``.
        chunk: Draws per compiled call.

    Raises:
        ParameterError: When the nominal drive or its operating point is outside the linearisation's scope.
    """
    check_nominal(drive, study, apply_sample)

    @eqx.filter_jit
    def matrices(rows):
        def one(row):
            d, s = apply_sample(drive, study, names, row)
            return linearise_traced(d, s.speed_ref.values[-1], s.load_torque.values[-1]).A

        return jax.vmap(one)(rows)

    start = time.perf_counter()
    n = values.shape[0]
    size = min(chunk, n)
    radii = np.empty(n)
    for lo in range(0, n, size):
        rows = values[lo : lo + size]
        pad = size - rows.shape[0]
        if pad:
            rows = np.concatenate([rows, np.repeat(rows[-1:], pad, axis=0)])
        A = np.asarray(matrices(jnp.asarray(rows, drive.machine.motor.R.dtype)), dtype=np.float64)
        radii[lo : lo + size - pad] = np.max(np.abs(np.linalg.eigvals(A)), axis=-1)[: size - pad]
    return radii, time.perf_counter() - start
