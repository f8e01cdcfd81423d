"""Parameters of a three-phase permanent-magnet synchronous motor (SI units)."""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

from pmsmjax._types import Array
from pmsmjax.spec.validation import ParameterError, check_nonnegative, check_positive


def as_float(x) -> Array:
    """Convert a number or array to a JAX float array of the default precision.

    Args:
        x: A number or array.
    """
    return jnp.asarray(x, dtype=jnp.result_type(float))


def optional_float(x) -> Array | None:
    """[`as_float`][pmsmjax.machines.motor.as_float], or None for None (an optional parameter left out)."""
    return None if x is None else as_float(x)


class PMSMParameters(eqx.Module):
    """Electrical and mechanical parameters of a three-phase PMSM.

    Every field but ``pole_pairs`` is an array leaf: tunable, vmappable and differentiable. Values may carry
    leading batch axes (one motor per row) when used under ``jax.vmap``.

    Args:
        R: Stator phase resistance, ohm.
        L_d: d-axis inductance, H.
        L_q: q-axis inductance, H (equal to ``L_d`` for a surface-mounted machine).
        psi_f: Permanent-magnet flux linkage amplitude (phase, peak), Wb.
        J: Total inertia on the shaft, kg m^2.
        B: Viscous friction coefficient, N m s/rad.
        pole_pairs: Number of pole pairs (static: it is an integer, not a tunable parameter).
        load_inertia: A compliant shaft's load inertia ``J_L``, kg m^2; ``J`` is then the motor's own
            inertia. None (default): a rigid shaft, ``J`` the total inertia
            ([`pmsmjax.machines.shaft`][pmsmjax.machines.shaft]).
        shaft_stiffness: The shaft's torsional stiffness ``K``, N m/rad (with ``load_inertia``).
        shaft_damping: The shaft's torsional damping ``D``, N m s/rad (with ``load_inertia``).

    Raises:
        ParameterError: For a non-integer or non-positive pole-pair count, or a non-positive resistance,
            inductance or inertia, or a negative flux or friction.
    """

    R: Array = eqx.field(converter=as_float)
    L_d: Array = eqx.field(converter=as_float)
    L_q: Array = eqx.field(converter=as_float)
    psi_f: Array = eqx.field(converter=as_float)
    J: Array = eqx.field(converter=as_float)
    B: Array = eqx.field(converter=as_float)
    pole_pairs: int = eqx.field(static=True, default=4)
    load_inertia: Array | None = eqx.field(default=None, converter=optional_float)
    shaft_stiffness: Array | None = eqx.field(default=None, converter=optional_float)
    shaft_damping: Array | None = eqx.field(default=None, converter=optional_float)
    #: Stator phases (the multi-phase parameters carry theirs as a field).
    n_phases: ClassVar[int] = 3
    #: Names of the leakage-inductance fields, H, that only the planes beyond the fundamental see (the
    #: multi-phase parameters' ``("L_ls",)``); none for three phases. The sub-step check and the Monte
    #: Carlo studies read them.
    leakage_fields: ClassVar[tuple[str, ...]] = ()

    def __check_init__(self):
        if not isinstance(self.pole_pairs, int) or self.pole_pairs < 1:
            raise ParameterError(
                f"pole_pairs must be a positive integer, got {self.pole_pairs!r}: give the number of "
                "pole pairs (poles/2) as an int."
            )
        check_positive("R (stator resistance)", self.R, "ohm")
        check_positive("L_d (d-axis inductance)", self.L_d, "H", "give inductances in henry (mH * 1e-3)")
        check_positive("L_q (q-axis inductance)", self.L_q, "H", "give inductances in henry (mH * 1e-3)")
        check_nonnegative("psi_f (PM flux linkage)", self.psi_f, "Wb")
        check_positive("J (inertia)", self.J, "kg m^2")
        check_nonnegative("B (viscous friction)", self.B, "N m s/rad")
        shaft = (self.load_inertia, self.shaft_stiffness, self.shaft_damping)
        if any(x is not None for x in shaft):
            if any(x is None for x in shaft):
                raise ParameterError(
                    "a compliant shaft needs load_inertia (kg m^2), shaft_stiffness (N m/rad) and "
                    "shaft_damping (N m s/rad): give all three, or none for a rigid shaft."
                )
            check_positive("load_inertia (shaft's load inertia)", self.load_inertia, "kg m^2")
            check_positive("shaft_stiffness (torsional stiffness)", self.shaft_stiffness, "N m/rad")
            check_nonnegative("shaft_damping (torsional damping)", self.shaft_damping, "N m s/rad")

    @property
    def total_inertia(self) -> Array:
        """Inertia of motor and load together, kg m^2: ``J``, plus ``load_inertia`` with a compliant shaft."""
        return self.J if self.load_inertia is None else self.J + self.load_inertia

    @property
    def torque_constant(self) -> Array:
        """1.5 p_n psi_f, N m/A (q-axis current to torque, amplitude-invariant frames)."""
        return 1.5 * self.pole_pairs * self.psi_f
