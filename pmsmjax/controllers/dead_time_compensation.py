"""Dead-time compensation: the controller adds the inverter's predicted voltage error back to its command.

Drive firmware knows its inverter's dead time ``t_d`` and, roughly, its device drop ``V_f``; the legs'
period-average error is ``-(U_dc t_d / Ts + V_f) sgn(i_x)``
([`pmsmjax.inverters.voltage_error`][pmsmjax.inverters.voltage_error]), so adding
``+(U_dc t_d / Ts + V_f) sgn(i_x)`` to each leg's command cancels it on average (the feed-forward of Murai et
al., IEEE Trans. Ind. Appl. 23(5), 1987, doi:10.1109/TIA.1987.4505004; Choi and Sul, IEEE Trans. Power
Electron. 11(2), 1996, doi:10.1109/63.486173).

The sign is that of the phase current while the command is applied: the period after the sample with a
computational delay, the sampled one without. It is predicted from the dq current (the loop's reference,
which does not carry the measured ripple and noise, or the measured current in the estimated frame)
turned ahead by ``omega_e (0.5 + delay) Ts``, the angle at the middle of that period, and smoothed as the
bridge model smooths it (``tanh(i / i_eps)``). The common mode of the three corrections does not reach the
machine and is dropped: the correction is a stator-frame voltage added to the current loop's command.
The controller's estimates may differ from the plant's inverter (a mis-compensation study).
"""

from typing import Literal

import equinox as eqx

from pmsmjax._types import Array
from pmsmjax.frames.three_phase import abc_to_alpha_beta, dq_to_abc
from pmsmjax.inverters.voltage_error import VoltageError
from pmsmjax.spec.validation import check_choice

__all__ = ["DeadTimeCompensation"]

CurrentSource = Literal["reference", "measured"]


class DeadTimeCompensation(eqx.Module):
    """The feed-forward of the inverter's predicted voltage error (module docstring).

    **Arguments:**

    - `estimate`: the controller's [`VoltageError`][pmsmjax.inverters.voltage_error.VoltageError] (its ``t_d``
      s, ``V_f`` V and sign smoothing ``i_eps`` A).
    - `current_source` (static): ``"reference"`` (default) or ``"measured"``, the dq current whose
      phase signs are predicted.
    """

    estimate: VoltageError
    current_source: CurrentSource = eqx.field(static=True, default="reference")

    def __check_init__(self):
        check_choice("current_source", self.current_source, ("reference", "measured"))

    def voltage_ab(self, i_dq_ref, i_dq_measured, theta_e, omega_e, u_dc, Ts, delayed: bool) -> Array:
        """``(2,)`` stator-frame voltage, V, to add to the command: minus the predicted error.

        ``i_dq_ref``, ``i_dq_measured``: ``(2,)`` A in the estimated frame at angle ``theta_e`` rad;
        ``omega_e`` rad/s; ``u_dc`` V; ``Ts`` s; ``delayed``: whether the command is applied one period
        late (static)."""
        i_dq = i_dq_ref if self.current_source == "reference" else i_dq_measured
        ahead = omega_e * (0.5 + float(delayed)) * Ts
        i_abc = dq_to_abc(i_dq, theta_e + ahead)
        # The duties are not known before modulation: take the error of a leg that switches with room
        # for both dead windows (duty 0.5), the full -(U_dc t_d / Ts + V_f) sgn(i).
        error = self.estimate.pole_error(i_abc, 0.5 + 0.0 * i_abc, u_dc, Ts)
        return -abc_to_alpha_beta(error)  # Clarke drops the common mode
