"""The values that flow between the blocks of a drive in one control period (the
sampled-data step of [`pmsmjax.drive`][pmsmjax.drive]).

``Sample`` (what the controller's hardware measures at the period start) -> estimator -> ``Estimate`` ->
controller (with the ``References``) -> ``ControlOutput``. Controllers read only these, never the plant's
state, so a sensorless drive is the same drive with another estimator.
"""

from typing import Literal

import equinox as eqx

from pmsmjax._types import Array

#: What a controller commands: a stationary-frame voltage for a modulator (``"voltage"``), or the leg
#: switch states directly (``"switches"``: hysteresis current control, table DTC).
CommandKind = Literal["voltage", "switches"]


class Sample(eqx.Module):
    """Measured at the start of a control period.

    Attributes:
        i_phase: ``(n,)`` phase currents, A.
        i_ab: ``(2,)`` the same currents in the stationary (alpha-beta) plane, A.
        u_dc: DC-link voltage, V.
        u_ab_last: ``(2,)`` stator-frame voltage commanded over the last period (period average of the
            duties that were applied, times ``u_dc``), V: what the controller knows it applied, without the
            inverter's dead-time error.
        sensor_theta_e: The shaft position sensor's reading as an electrical angle, rad; an ideal sensor.
            An encoder model quantises and delays it; sensorless estimators ignore it.
        sensor_omega_m: The ideal shaft speed, rad/s (for the exact sensor; an encoder differentiates its
            angle instead).
    """

    i_phase: Array
    i_ab: Array
    u_dc: Array
    u_ab_last: Array
    sensor_theta_e: Array
    sensor_omega_m: Array


class Estimate(eqx.Module):
    """What an estimator tells the controller.

    Attributes:
        theta_e: Electrical rotor angle (d axis from the A axis), rad.
        omega_m: Mechanical speed, rad/s.
        u_injection_ab: ``(2,)`` stator-frame voltage to add to the controller's command, V (HF injection);
            ``None`` for estimators that inject nothing.
        psi_ab: ``(2,)`` stator flux linkage in the stationary frame, Wb; ``None`` for estimators that do
            not estimate it (direct torque control needs it:
            [`pmsmjax.estimators.flux_observer`][pmsmjax.estimators.flux_observer]).
        torque: Electromagnetic torque, N m; ``None`` where not estimated.
        back_emf_ab: ``(2,)`` the observer's stationary-frame back-EMF estimate at the sampling instant, V
            (chapter 5 observers); ``None`` for position sensors.
        startup_weight: Weight in [0, 1] of the start-up current reference ``startup_i_dq`` in the
            controller's current reference (1: open-loop I/f start, 0: speed loop in charge); ``None`` for
            estimators without a start-up ([`pmsmjax.estimators.startup`][pmsmjax.estimators.startup]).
        startup_i_dq: ``(2,)`` the start-up current reference in the estimate's frame, A; ``None`` likewise.
        i_ab_fundamental: ``(2,)`` stationary-frame current with the injected carrier filtered out, A: the
            drive gives it to the controller in place of the sampled ``i_ab`` so that the current loop never
            acts on the carrier (HF injection,
            [`pmsmjax.estimators.hfi_signal`][pmsmjax.estimators.hfi_signal]); ``None``: the controller gets
            the sampled currents.
    """

    theta_e: Array
    omega_m: Array
    u_injection_ab: Array | None = None
    psi_ab: Array | None = None
    torque: Array | None = None
    back_emf_ab: Array | None = None
    startup_weight: Array | None = None
    startup_i_dq: Array | None = None
    i_ab_fundamental: Array | None = None


class References(eqx.Module):
    """Reference values for one period.

    In speed mode the speed loop makes ``i_q*`` and ``iq_ref`` is ignored; ``id_ref`` is the d-axis
    reference unless a flux-weakening/MTPA block sets it.

    Attributes:
        speed_ref: Speed reference, mechanical rad/s.
        id_ref: d-axis current reference, A.
        iq_ref: q-axis current reference, A.
        iq_ref_perturbation: A, added to the q-current reference after the speed controller (the speed
            loop's break point, for a loop-response measurement), or None.
    """

    speed_ref: Array
    id_ref: Array
    iq_ref: Array
    iq_ref_perturbation: Array | None = None


class ControlOutput(eqx.Module):
    """A controller's output for one period.

    Attributes:
        command: ``(2,)`` stator-frame voltage reference, V, for ``command_kind == "voltage"``; ``(n,)`` leg
            switch states in {0, 1} held over the period for ``command_kind == "switches"``.
        u_dq_ref: ``(2,)`` the voltage command in the controller's (estimated) rotor frame, V; for switching
            controllers the voltage of the chosen switch states.
        i_dq_ref: ``(2,)`` current reference, A.
    """

    command: Array
    u_dq_ref: Array
    i_dq_ref: Array
