"""Anticogging: a feed-forward q current over the rotor angle, added to the current loop's reference.

A cogging torque ``T_cog(theta)`` repeats with the rotor's position; a q current ``i_q,ff(theta) ~ -T_cog /
(1.5 p psi_f)`` cancels it before the speed loop has to. ODrive's firmware calibrates such a table by
stepping its position setpoint slowly through the encoder counts and storing the velocity integrator's
current at each (ODrive, ``Firmware/MotorControl/controller.cpp``); here the table is a differentiable
block learnt by gradients through the closed loop (`tuning.autotune.anticogging`).

**Table.** ``N`` values ``i_q[j]`` at ``theta_e = 2 pi j / N`` over one **electrical** revolution,
interpolated linearly and periodically. Per electrical revolution because the plant's cogging and flux
harmonics are periodic in ``theta_e`` ([`pmsmjax.machines.harmonics`][pmsmjax.machines.harmonics]: a motor
with ``Q`` slots and ``2p`` poles cogs ``lcm(Q, 2p) / p`` times per electrical revolution), so a mechanical
table would hold the same shape ``p`` times, each copy learnt from ``1/p`` of the samples; the controller
reads ``theta_e`` from its estimator. (A real motor's eccentricity and magnet tolerances repeat per
mechanical revolution, which ODrive's per-count table captures and this one does not.) ``N`` must resolve
the highest cogging order ``n``: a piecewise-linear fit of ``sin(n theta)`` with ``N / n`` points per period
leaves about ``(pi n / N)^2 / 12`` of its amplitude (at ``N = 128``, ``n = 12``: 1 %).

The feed-forward is added after the speed loop (whose integrator then no longer sees the cogging) and is not
limited separately: it is small against the current limit by construction (cogging is a few per cent of the
rated torque).
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from pmsmjax._types import Array
from pmsmjax.machines.motor import as_float
from pmsmjax.spec.validation import ParameterError, check_finite

__all__ = ["AnticoggingTable"]


class AnticoggingTable(eqx.Module):
    """Feed-forward q current over one electrical revolution (module docstring).

    Args:
        iq_a: ``(N,)`` q current at ``theta_e = 2 pi j / N``, A; an array leaf (tunable, vmappable,
            differentiable). ``N >= 2``.

    Raises:
        ParameterError: For fewer than 2 bins or non-finite values.
    """

    iq_a: Array = eqx.field(converter=as_float)

    def __check_init__(self):
        if self.iq_a.ndim < 1 or self.iq_a.shape[-1] < 2:
            raise ParameterError(
                f"AnticoggingTable.iq_a must hold N >= 2 values over one electrical revolution, got shape "
                f"{self.iq_a.shape}."
            )
        check_finite("AnticoggingTable.iq_a", self.iq_a, "A")

    @classmethod
    def zeros(cls, n_bins: int = 128, dtype=None) -> "AnticoggingTable":
        """An empty table of ``n_bins`` bins (the starting point of learning)."""
        return cls(jnp.zeros(n_bins, dtype or jnp.result_type(float)))

    @property
    def n_bins(self) -> int:
        """``N``, the bins over one electrical revolution (static)."""
        return int(self.iq_a.shape[-1])

    @property
    def angles(self) -> np.ndarray:
        """``(N,)`` the bins' electrical angles ``2 pi j / N``, rad."""
        return 2.0 * np.pi * np.arange(self.n_bins) / self.n_bins

    def current(self, theta_e) -> Array:
        """The feed-forward q current at the electrical angle ``theta_e`` (rad, any turn), A: linear
        interpolation between the two nearest bins, periodic."""
        n = self.n_bins
        x = jnp.mod(theta_e, 2.0 * np.pi) * (n / (2.0 * np.pi))
        j = jnp.floor(x)
        f = x - j
        j0 = j.astype(jnp.int32) % n
        j1 = (j0 + 1) % n
        return (1.0 - f) * self.iq_a[..., j0] + f * self.iq_a[..., j1]
