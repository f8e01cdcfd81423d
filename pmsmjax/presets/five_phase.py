"""The five-phase reference motor and drives (the book, ch. 10).

**Motor: the book motor rewound as a symmetrical five-phase machine with the same copper.** The book's text
gives no five-phase parameters, so the preset is derived from the three-phase book motor (p_n = 4,
R = 0.958 ohm, L_d = L_q = 5.25 mH or L_q = 12 mH salient, psi_f = 0.1827 Wb, J = 0.003 kg m^2,
B = 0.008 N m s) by rewinding its stator into five phases at 72 degrees with the same total number of
turns: each phase gets ``N5 = (3/5) N3`` turns of the same conductor (same slot fill, same copper mass),
the same winding factor assumed. Per phase:

- ``psi_f`` proportional to N: ``(3/5) 0.1827 = 0.10962`` Wb;
- ``R``: 3/5 of the conductor length: ``(3/5) 0.958 = 0.5748`` ohm;
- a phase's magnetising inductances ``L_0m``, ``L_2m`` and leakage ``L_ls`` proportional to N^2:
  ``(3/5)^2 = 0.36`` of the three-phase machine's. The three-phase leakage is not given; the project takes
  ``L_ls3 = 0.1 L_d = 0.525 mH`` (as the six-phase preset), so ``L_ls = 0.189`` mH;
- hence, in VSD coordinates (``L_d - L_ls = (5/2)(L_0m + L_2m)`` against ``(3/2)(...)`` with three phases):
  ``L_d5 = L_ls5 + (5/2)(0.36)/(3/2) (L_d3 - L_ls3) = L_ls5 + (3/5)(L_d3 - L_ls3) = 3.024 mH``,
  ``L_q5 = 3.024 mH`` (salient: ``0.189 + 0.6 (12 - 0.525) = 7.074`` mH);
- mechanics unchanged (same rotor): J, B, p_n.

Consequences, by construction: the stator MMF per ampere of ``i_q`` is the book motor's (``(5/2) N5 =
(3/2) N3``), so the torque constant ``2.5 p_n psi_f5 = 1.5 p_n psi_f3 = 1.0962 N m/A`` is the same (10 N m
needs i_q = 9.12 A, the same phase-current amplitude), and so are the copper loss at a given torque
(``(5/2) R5 I^2 = (3/2) R3 I^2``) and the field energy. The back-EMF per phase is 3/5 of the book motor's
(45.9 V peak at 1000 r/min) against a linear limit of ``0.5257 U_dc = 163.5`` V (near-four-vector SVPWM or
min-max carrier PWM at 311 V). The x-y subspace sees only the leakage: ``L_ls/R = 0.33 ms`` against the
fundamental's ``L_d/R = 5.3 ms``.

**Third-harmonic back-EMF** (optional, off by default): ``five_phase_motor(third_harmonic=0.1)`` sets
``psi_f3 = 0.1 psi_f`` (a magnet shape with a flatter-topped back-EMF; the fraction is the caller's
choice, the book gives none). It makes x-y currents produce torque
([`pmsmjax.machines.pmsm_multiphase`][pmsmjax.machines.pmsm_multiphase]); the drives here keep the x-y current
reference at zero, so it is a disturbance the x-y loops reject (in the third-harmonic frame it is a constant
voltage).

The same numbers are in the motor file ``pmsmjax/presets/motors/five_phase_book.toml``.

**Drives** (`five_phase_drive`): the book drive's settings (311 V, 10 kHz, one-period computational
delay, design-rule gains at a_c = 1100 rad/s and beta = 50 rad/s, 15 A limit) with a control of
[`FIVE_PHASE_CONTROLS`][pmsmjax.presets.five_phase.FIVE_PHASE_CONTROLS] and a modulator of
[`FIVE_PHASE_PWMS`][pmsmjax.presets.five_phase.FIVE_PHASE_PWMS]; the controller is the n-phase cascade
[`MultiPhaseFOC`][pmsmjax.controllers.multiphase.MultiPhaseFOC] with the five-phase VSD current block (dq PI
+ x-y PI in the frame at ``3 theta_e``), the bridges the n-leg ones
([`pmsmjax.inverters.multiphase_bridges`][pmsmjax.inverters.multiphase_bridges]) with the five-phase layout.
"""

from pathlib import Path

from pmsmjax.controllers.design import current_loop_imc
from pmsmjax.controllers.multiphase import VSDCurrentControl
from pmsmjax.controllers.multiphase_design import vsd_current_design, z_pr_design
from pmsmjax.controllers.pr import pr_design
from pmsmjax.frames.multiphase import FIVE_PHASE
from pmsmjax.inverters.multiphase_carrier import ZeroSequencePWM
from pmsmjax.inverters.multiphase_svpwm import LargeVectorSVPWM, NearFourVectorSVPWM
from pmsmjax.machines.multiphase_motor import MultiPhaseParameters
from pmsmjax.machines.pmsm_multiphase import MultiPhasePMSMdq, MultiPhasePMSMVSD
from pmsmjax.machines.pmsm_multiphase_natural import MultiPhasePMSMNatural
from pmsmjax.presets.multiphase import machine_controls, multiphase_drive_function, multiphase_machine
from pmsmjax.presets.six_phase import THREE_PHASE_LEAKAGE_FRACTION, read_multiphase_motor_file
from pmsmjax.presets.three_phase import PR_W_C, book_motor
from pmsmjax.spec.validation import ParameterError

__all__ = [
    "FIVE_PHASE_CONTROLS",
    "FIVE_PHASE_FRAMES",
    "FIVE_PHASE_MOTOR_FILE",
    "FIVE_PHASE_PWMS",
    "XY_ROTATION",
    "five_phase_drive",
    "five_phase_machine",
    "five_phase_motor",
    "load_five_phase_motor",
]

#: Turns per phase of the five-phase rewind relative to the three-phase book motor's (same total turns).
TURNS_RATIO = 3.0 / 5.0
#: The x-y PI's frame: at ``3 theta_e`` (the third-harmonic synchronous frame).
XY_ROTATION = 3
FIVE_PHASE_MOTOR_FILE = Path(__file__).resolve().parent / "motors" / "five_phase_book.toml"


def five_phase_motor(salient: bool = False, third_harmonic: float | None = None) -> MultiPhaseParameters:
    """The book motor rewound as a five-phase machine with the same copper (module docstring);
    `third_harmonic`: ``psi_f3 / psi_f`` or None (no third-harmonic back-EMF)."""
    m = book_motor(salient)
    k = TURNS_RATIO
    L_ls3 = THREE_PHASE_LEAKAGE_FRACTION * m.L_d
    L_ls = k * k * L_ls3
    psi_f = k * m.psi_f
    return MultiPhaseParameters(
        R=k * m.R,
        L_d=L_ls + k * (m.L_d - L_ls3),
        L_q=L_ls + k * (m.L_q - L_ls3),
        psi_f=psi_f,
        L_ls=L_ls,
        J=m.J,
        B=m.B,
        pole_pairs=m.pole_pairs,
        n_phases=5,
        psi_f3=None if third_harmonic is None else third_harmonic * psi_f,
    )


def load_five_phase_motor(name_or_path) -> MultiPhaseParameters:
    """A five-phase motor by preset name (``book``, ``book_salient``) or from a TOML file with ``R, L_d,
    L_q, psi_f, L_ls, pole_pairs, J, B``, optionally ``psi_f3`` and ``n_phases = 5``, at top level or under
    ``[motor]``, SI units."""
    key = str(name_or_path)
    if key in ("book", "book_salient"):
        return five_phase_motor(key == "book_salient")
    return read_multiphase_motor_file(name_or_path, 5, optional=("psi_f3",))


#: Machine model frames: ``dq`` (fundamental in the rotor frame, x-y stationary: the fast one), ``vsd``
#: (stationary VSD), ``natural`` (5x5 phase inductances).
FIVE_PHASE_FRAMES = {"dq": MultiPhasePMSMdq, "vsd": MultiPhasePMSMVSD, "natural": MultiPhasePMSMNatural}


def _nfv():
    return NearFourVectorSVPWM(FIVE_PHASE)


def _carrier():
    return ZeroSequencePWM(FIVE_PHASE, "min-max")


def _sinusoidal():
    return ZeroSequencePWM(FIVE_PHASE, "none", name="sinusoidal")


def _large():
    return LargeVectorSVPWM(FIVE_PHASE)


#: Modulators (the book, ch. 10): near-four-vector SVPWM, carrier PWM with min-max zero-sequence
#: injection, sinusoidal carrier PWM (no injection; the reference point for DC-link use), and the
#: two-large-vector SVPWM (x-y uncontrolled: the contrast that shows why the near-four-vector method).
FIVE_PHASE_PWMS = {
    "near-four-vector": _nfv,
    "carrier": _carrier,
    "sinusoidal": _sinusoidal,
    "large-vector": _large,
}

#: Control schemes by name -> one-line description (`pmsmjax.spec.registry.REGISTRY`).
FIVE_PHASE_CONTROLS = machine_controls("five-phase")


def five_phase_machine(motor=None, frame: str = "dq", mechanics: str = "dynamic", resistance_scale=None):
    """The five-phase machine model of ``motor`` in ``frame``
    ([`FIVE_PHASE_FRAMES`][pmsmjax.presets.five_phase.FIVE_PHASE_FRAMES])."""
    motor = five_phase_motor() if motor is None else motor
    return multiphase_machine(
        "five-phase", FIVE_PHASE_FRAMES, motor, frame, mechanics, resistance_scale, layout=FIVE_PHASE
    )


def five_phase_current_block(control: str, motor, current_bandwidth: float, w_c: float = PR_W_C):
    """The five-phase current block of ``control``
    ([`FIVE_PHASE_CONTROLS`][pmsmjax.presets.five_phase.FIVE_PHASE_CONTROLS]) from the design rules.

    ``pr``: the alpha-beta PR ([`pr_design`][pmsmjax.controllers.pr.pr_design]) and the x-y PR
    ([`z_pr_design`][pmsmjax.controllers.multiphase_design.z_pr_design]), both resonant at ``w_e``: a
    phase-resistance unbalance puts x-y currents at ``+-w_e`` (not constant in the ``3 theta_e`` frame of the
    ``vsd`` x-y PI, which removes third-harmonic disturbances instead); a real-coefficient resonator at
    ``w_e`` removes both directions."""
    if control == "vsd":
        return vsd_current_design(motor, current_bandwidth, layout=FIVE_PHASE, rotation=XY_ROTATION)
    if control == "conventional":
        return VSDCurrentControl(current_loop_imc(motor, current_bandwidth), None, FIVE_PHASE)
    if control == "pr":
        return VSDCurrentControl(
            pr_design(motor, current_bandwidth, w_c), z_pr_design(motor, current_bandwidth, w_c), FIVE_PHASE
        )
    raise ParameterError(
        f"five-phase control must be one of {', '.join(FIVE_PHASE_CONTROLS)}, got {control!r}."
    )


five_phase_drive = multiphase_drive_function(
    "five_phase_drive",
    __name__,
    """A five-phase drive: `control`
    ([`FIVE_PHASE_CONTROLS`][pmsmjax.presets.five_phase.FIVE_PHASE_CONTROLS]), `pwm`
    ([`FIVE_PHASE_PWMS`][pmsmjax.presets.five_phase.FIVE_PHASE_PWMS]), `bridge` (``averaged`` or
    ``switching``, the latter with optional `dead_time` s), `frame`
    ([`FIVE_PHASE_FRAMES`][pmsmjax.presets.five_phase.FIVE_PHASE_FRAMES]); the rest as
    [`pmsmjax.presets.book_drive`][pmsmjax.presets.three_phase.book_drive]. `resistance_scale`: ``(5,)`` phase
    resistance factors of the plant (unbalance); `w_c` rad/s: the PR resonators' damping.

    The controller's model is the plant's motor (its ``psi_f3`` unused by the controller): the speed PI
    with active damping at ``speed_bandwidth``, the current loops at ``current_bandwidth``.
    """,
    machine="five-phase",
    layout=FIVE_PHASE,
    default_motor=five_phase_motor,
    pwms=FIVE_PHASE_PWMS,
    default_pwm="near-four-vector",
    machine_model=five_phase_machine,
    current_block=five_phase_current_block,
)
