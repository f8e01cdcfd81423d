"""The book's reference motor, drive and scenario as plain numbers, each defined here once.

docs/book_reference.md, "Reference motor and scenario (three-phase, chapters 1-6)" and chapter 3
(the design-rule bandwidths). Plain Python (no JAX), so that the command line reads these for the checks
it makes before JAX starts; every preset, command and workflow takes its book value from here.
"""

from types import MappingProxyType

# The motor (SI units).
#: Pole pairs p_n.
BOOK_POLE_PAIRS = 4
#: Stator resistance R, ohm.
BOOK_R_OHM = 0.958
#: d- and q-axis inductance of the surface machine, H.
BOOK_L_H = 5.25e-3
#: q-axis inductance of the salient variant used for HF injection (L_d stays BOOK_L_H), H.
BOOK_SALIENT_L_Q_H = 12e-3
#: Permanent-magnet flux linkage psi_f, Wb.
BOOK_PSI_F_WB = 0.1827
#: Rotor and load inertia J, kg m^2.
BOOK_J_KG_M2 = 0.003
#: Viscous friction B, N m s/rad.
BOOK_B_NM_S = 0.008

#: The surface motor as the fields of
#: [`pmsmjax.machines.motor.PMSMParameters`][pmsmjax.machines.motor.PMSMParameters] (SI units as above);
#: read-only (copy it to change a value).
BOOK_MOTOR = MappingProxyType(
    dict(
        R=BOOK_R_OHM,
        L_d=BOOK_L_H,
        L_q=BOOK_L_H,
        psi_f=BOOK_PSI_F_WB,
        pole_pairs=BOOK_POLE_PAIRS,
        J=BOOK_J_KG_M2,
        B=BOOK_B_NM_S,
    )
)
#: The salient variant (L_q = 12 mH), same fields.
BOOK_SALIENT_MOTOR = MappingProxyType({**BOOK_MOTOR, "L_q": BOOK_SALIENT_L_Q_H})

# The drive.
#: DC-link voltage U_dc, V.
BOOK_DC_LINK = 311.0
#: PWM and control period, s (10 kHz).
BOOK_TS = 1e-4
#: Peak phase-current limit, A. The design-rule speed loop asks for Kp_w * 104.7 rad/s = 14.3 A at the
#: 1000 r/min step; 15 A leaves that linear and 1.6x the 9.1 A the 10 N m load needs.
BOOK_CURRENT_LIMIT = 15.0
#: Current-loop bandwidth a_c of the internal-model PI design, rad/s (chapter 3).
BOOK_CURRENT_BANDWIDTH = 1100.0
#: Speed-loop bandwidth beta of the active-damping PI design, rad/s (chapter 3).
BOOK_SPEED_BANDWIDTH = 50.0

#: Comparator sample period of the hysteresis current control drive, s (100 kHz;
#: [`pmsmjax.presets.hysteresis_drive`][pmsmjax.presets.three_phase.hysteresis_drive] says why).
HYSTERESIS_SAMPLE_PERIOD_S = 10e-6
#: Comparator sample period of the switching-table DTC drive, s (40 kHz;
#: [`pmsmjax.presets.dtc_drive`][pmsmjax.presets.three_phase.dtc_drive]).
DTC_SAMPLE_PERIOD_S = 25e-6

# The scenario.
#: Speed step at t = 0, r/min.
BOOK_SPEED_STEP_RPM = 1000.0
#: Load step 0 -> this torque, N m.
BOOK_LOAD_NM = 10.0
#: Time of the load step, s.
BOOK_LOAD_TIME_S = 0.2
#: Length of the run, s.
BOOK_DURATION_S = 0.4
