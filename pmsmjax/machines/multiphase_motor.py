"""Parameters of a multi-phase (n-phase) PMSM, SI units (the book, ch. 7 and 10).

The same fields as [`pmsmjax.machines.motor.PMSMParameters`][pmsmjax.machines.motor.PMSMParameters] (so every
design rule and controller written for those reads them unchanged) plus the leakage inductance ``L_ls`` and
the phase count:

- ``L_d``, ``L_q``: the fundamental (alpha-beta) subspace's d- and q-axis inductances in VSD coordinates,
  ``L_d = L_ls + (n/2)(L_0m + L_2m)``, ``L_q = L_ls + (n/2)(L_0m - L_2m)`` with ``L_0m``, ``L_2m`` the
  mean and the saliency part of a phase's magnetising inductance (natural frame,
  [`pmsmjax.machines.pmsm_multiphase`][pmsmjax.machines.pmsm_multiphase]).
- ``L_ls``: phase leakage inductance, H: the only inductance the non-fundamental subspaces (six phases:
  z1-z2; five phases: x-y) and the zero sequences see, so it sets their harmonic and ripple currents.
  ``L_ls < min(L_d, L_q)`` (a positive magnetising inductance).
- ``psi_f``: PM flux linkage of one phase (peak), Wb.
- ``torque_constant``: ``(n/2) p_n psi_f`` (amplitude-invariant VSD; 3 p_n psi_f for six phases,
  the book, ch. 7; 2.5 p_n psi_f for five, ch. 10).
- ``psi_f3``: optional third-harmonic PM flux linkage of one phase (peak), Wb: the phase flux
  ``psi_f cos(th - g) + psi_f3 cos(3 (th - g))``. ``None`` (default) leaves it out of the program. For five
  phases it lies in the x-y plane (order 3), where x-y currents make torque with it
  ([`pmsmjax.machines.pmsm_multiphase`][pmsmjax.machines.pmsm_multiphase]); layouts without an order-3 plane
  refuse it (six phases: the third harmonic is each star's zero sequence, which isolated stars carry no
  current in).

Leakage is taken as the phase's own (diagonal) leakage; mutual leakage between phases sharing slots is
not modelled (it would lower the z1-z2 inductance below ``L_ls``).
"""

from typing import ClassVar

import equinox as eqx
import jax
import numpy as np

from pmsmjax._types import Array
from pmsmjax.machines import dq_equations as dq
from pmsmjax.machines.motor import as_float
from pmsmjax.spec.validation import ParameterError, check_nonnegative, check_positive, is_concrete


def _optional_float(x):
    return None if x is None else as_float(x)


class MultiPhaseParameters(eqx.Module):
    """Electrical and mechanical parameters of an n-phase PMSM (see the module docstring).

    Args:
        R: Phase resistance, ohm.
        L_d: d-axis inductance of the VSD fundamental subspace, H.
        L_q: q-axis inductance of the VSD fundamental subspace, H.
        psi_f: PM flux linkage (per phase, peak), Wb.
        L_ls: Phase leakage inductance, H (below ``min(L_d, L_q)``).
        J: Total inertia on the shaft, kg m^2.
        B: Viscous friction coefficient, N m s/rad.
        pole_pairs: Number of pole pairs (static int).
        n_phases: Number of phases (static int, at least 3).
        psi_f3: Third-harmonic PM flux (peak), Wb, or ``None`` (none).

    Raises:
        ParameterError: For a non-positive resistance, inductance or inertia, a negative flux or friction,
            bad integer counts, or a leakage not below the axis inductances.
    """

    R: Array = eqx.field(converter=as_float)
    L_d: Array = eqx.field(converter=as_float)
    L_q: Array = eqx.field(converter=as_float)
    psi_f: Array = eqx.field(converter=as_float)
    L_ls: Array = eqx.field(converter=as_float)
    J: Array = eqx.field(converter=as_float)
    B: Array = eqx.field(converter=as_float)
    pole_pairs: int = eqx.field(static=True, default=4)
    n_phases: int = eqx.field(static=True, default=6)
    psi_f3: Array | None = eqx.field(default=None, converter=_optional_float)
    #: The leakage inductance's field (see
    #: [`PMSMParameters.leakage_fields`][pmsmjax.machines.motor.PMSMParameters.leakage_fields]).
    leakage_fields: ClassVar[tuple[str, ...]] = ("L_ls",)

    def __check_init__(self):
        if not isinstance(self.pole_pairs, int) or self.pole_pairs < 1:
            raise ParameterError(
                f"pole_pairs must be a positive integer, got {self.pole_pairs!r}: give the number of "
                "pole pairs (poles/2) as an int."
            )
        if not isinstance(self.n_phases, int) or self.n_phases < 3:
            raise ParameterError(f"n_phases must be an int >= 3, got {self.n_phases!r}.")
        check_positive("R (stator resistance)", self.R, "ohm")
        hint = "give inductances in henry (mH * 1e-3)"
        check_positive("L_d (d-axis inductance)", self.L_d, "H", hint)
        check_positive("L_q (q-axis inductance)", self.L_q, "H", hint)
        check_positive("L_ls (phase leakage inductance)", self.L_ls, "H", hint)
        check_nonnegative("psi_f (PM flux linkage)", self.psi_f, "Wb")
        check_positive("J (inertia)", self.J, "kg m^2")
        check_nonnegative("B (viscous friction)", self.B, "N m s/rad")
        if all(is_concrete(x) for x in (self.L_d, self.L_q, self.L_ls)):
            L_d, L_q, L_ls = (np.asarray(jax.device_get(x), float) for x in (self.L_d, self.L_q, self.L_ls))
            if np.any(L_ls >= np.minimum(L_d, L_q)):
                raise ParameterError(
                    f"L_ls (phase leakage inductance) = {np.max(L_ls):g} H must be below min(L_d, L_q) = "
                    f"{np.min(np.minimum(L_d, L_q)):g} H: the rest of L_d, L_q is the magnetising "
                    "inductance, which must be positive."
                )

    @property
    def torque_constant(self) -> Array:
        """(n/2) p_n psi_f, N m/A (q-axis current to torque, amplitude-invariant VSD)."""
        return 0.5 * self.n_phases * self.pole_pairs * self.psi_f

    @property
    def torque_factor(self) -> float:
        """``n/2 p_n``: ``T_e = torque_factor [psi_f i_q + (L_d - L_q) i_d i_q]``."""
        return dq.torque_factor(self.pole_pairs, self.n_phases)
