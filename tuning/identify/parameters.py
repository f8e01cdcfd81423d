"""Free and fixed model parameters as one well-scaled vector for the least-squares solver.

A free positive parameter (R, L_d, L_q, psi_f, J, B) is ``start * exp(theta)``: positive by
construction, and ``theta`` is a relative change (0.01 = 1 %), so every unknown has the same scale
whatever its unit. A free signed parameter (a constant load torque, a dead-time voltage) is
``start + scale * theta``. Fixed parameters keep their given value and take no place in ``theta``.
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from pmsmjax._types import Array

__all__ = ["ParameterMap"]


class ParameterMap(eqx.Module):
    """Maps the solver's ``theta (n_free,)`` to named parameter values.

    - `names`: parameter names (static); `free`, `positive`: one flag per name (static).
    - `start`: ``(n,)`` start values (free) or the values (fixed), SI units.
    - `scale`: ``(n,)`` step scale of signed parameters (unused for positive ones), SI units.
    """

    names: tuple[str, ...] = eqx.field(static=True)
    free: tuple[bool, ...] = eqx.field(static=True)
    positive: tuple[bool, ...] = eqx.field(static=True)
    start: Array
    scale: Array

    @property
    def free_names(self) -> tuple[str, ...]:
        """Names of the free parameters, in the order of ``theta``."""
        return tuple(n for n, f in zip(self.names, self.free, strict=True) if f)

    @property
    def n_free(self) -> int:
        """Number of free parameters (the length of ``theta``)."""
        return sum(self.free)

    def values(self, theta: Array) -> dict[str, Array]:
        """``{name: scalar}`` for every parameter at ``theta (n_free,)``."""
        out, j = {}, 0
        for k, name in enumerate(self.names):
            if self.free[k]:
                t = theta[j]
                j += 1
                if self.positive[k]:
                    out[name] = self.start[k] * jnp.exp(t)
                else:
                    out[name] = self.start[k] + self.scale[k] * t
            else:
                out[name] = self.start[k]
        return out

    def value_jacobian(self, theta: np.ndarray) -> np.ndarray:
        """``(n_free,)`` d value / d theta of each free parameter (diagonal), for the delta method."""
        d, j = [], 0
        for k in range(len(self.names)):
            if self.free[k]:
                s = float(self.start[k])
                d.append(s * np.exp(theta[j]) if self.positive[k] else float(self.scale[k]))
                j += 1
        return np.asarray(d)

    def restart(self, theta: np.ndarray) -> "ParameterMap":
        """The same map with its start moved to ``theta`` (so the new start is ``theta = 0``)."""
        vals = self.values(jnp.asarray(theta))
        return ParameterMap(
            self.names,
            self.free,
            self.positive,
            jnp.asarray([vals[n] for n in self.names]),
            self.scale,
        )
