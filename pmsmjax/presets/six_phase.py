"""The six-phase (dual three-phase) reference motor and drives (the book, ch. 7-9).

**Motor: the book motor rewound as a dual three-phase machine with the same copper.** The book's text gives
no six-phase parameters, so the preset is derived from the three-phase book motor (p_n = 4, R = 0.958 ohm,
L_d = L_q = 5.25 mH or L_q = 12 mH salient, psi_f = 0.1827 Wb, J = 0.003 kg m^2, B = 0.008 N m s) by
rewinding its stator: each slot's coil is split into two coils of half the turns, one per three-phase set,
the second set's coils in the slots 30 electrical degrees on (the standard dual three-phase winding of a
machine with a whole number of slots per pole and phase of at least 2). Per phase, with the turns ``N``
halved and the copper cross-section per turn unchanged:

- ``psi_f`` proportional to N: 0.1827/2 = 0.09135 Wb;
- ``R``: half the length of the same conductor: 0.958/2 = 0.479 ohm;
- the phase's magnetising inductances ``L_0m``, ``L_2m`` and leakage ``L_ls`` proportional to N^2: a
  quarter of the three-phase machine's. The three-phase machine's leakage is not given; the project takes
  ``L_ls3 = 0.1 L_d = 0.525 mH`` ([`pmsmjax.machines.PMSMabc`][pmsmjax.machines.pmsm3.PMSMabc]'s default), so
  ``L_ls = 0.131 mH``;
- hence, in VSD coordinates (``L_d = L_ls + 3 (L_0m + L_2m)`` with six phases against ``L_ls + 1.5 (...)``
  with three): ``L_d6 = L_d3/2 - L_ls3/4 = 2.494 mH``, ``L_q6 = 2.494 mH`` (salient: 12/2 - 0.131 =
  5.869 mH);
- mechanics unchanged (same rotor): J, B, p_n.

Consequences, by construction: the torque constant ``3 p_n psi_f6 = 1.5 p_n psi_f3 = 1.0962 N m/A`` is the
book motor's (10 N m needs i_q = 9.12 A, the same phase currents), the copper loss at a given torque is the
same (``6 (R/2) I^2/2 = 3 R I^2/2``), and the back-EMF per phase is halved (38 V peak at 1000 r/min), so
the 311 V link has twice the voltage margin. Mutual leakage between the two coils sharing a slot is not
modelled (it would lower the z1-z2 inductance below ``L_ls``). The z1-z2 subspace's impedance is small:
``L_ls/R = 0.27 ms`` against the fundamental's ``L_d/R = 5.2 ms``, which is why its voltage must be
controlled (four-vector SVPWM, z1-z2 current loops). The same numbers are in the motor file
``pmsmjax/presets/motors/six_phase_book.toml``.

**Drives** (`six_phase_drive`): the book drive's settings (311 V,
10 kHz, one-period computational delay, design-rule gains at a_c = 1100 rad/s and beta = 50 rad/s, 15 A limit)
with a control scheme of [`SIX_PHASE_CONTROLS`][pmsmjax.presets.six_phase.SIX_PHASE_CONTROLS] and a modulator
of [`SIX_PHASE_PWMS`][pmsmjax.presets.six_phase.SIX_PHASE_PWMS].
"""

from pathlib import Path

from pmsmjax.controllers.design import current_loop_imc
from pmsmjax.controllers.multiphase import VSDCurrentControl
from pmsmjax.controllers.multiphase_design import double_dq_design, pr_current_design, vsd_current_design
from pmsmjax.frames.multiphase import SIX_PHASE
from pmsmjax.inverters.decoupled_svpwm import DecoupledSVPWM
from pmsmjax.inverters.multiphase_carrier import ZeroSequencePWM
from pmsmjax.inverters.multiphase_svpwm import LargeVectorSVPWM, NearFourVectorSVPWM
from pmsmjax.io.toml_parser import tomllib
from pmsmjax.machines.multiphase_motor import MultiPhaseParameters
from pmsmjax.machines.pmsm6 import PMSM6DoubleDQ
from pmsmjax.machines.pmsm_multiphase import MultiPhasePMSMdq, MultiPhasePMSMVSD
from pmsmjax.machines.pmsm_multiphase_natural import MultiPhasePMSMNatural
from pmsmjax.presets.multiphase import machine_controls, multiphase_drive_function, multiphase_machine
from pmsmjax.presets.three_phase import PR_W_C, book_motor
from pmsmjax.spec.validation import ParameterError

__all__ = [
    "SIX_PHASE_CONTROLS",
    "SIX_PHASE_FRAMES",
    "SIX_PHASE_PWMS",
    "SIX_PHASE_MOTOR_FILE",
    "load_six_phase_motor",
    "six_phase_drive",
    "six_phase_machine",
    "six_phase_motor",
]

#: Leakage of the three-phase book motor assumed by the derivation, as a fraction of its L_d.
THREE_PHASE_LEAKAGE_FRACTION = 0.1
#: The motor file with the six-phase preset's numbers.
SIX_PHASE_MOTOR_FILE = Path(__file__).resolve().parent / "motors" / "six_phase_book.toml"

SIX_PHASE_FIELDS = ("R", "L_d", "L_q", "psi_f", "L_ls", "pole_pairs", "J", "B")


def six_phase_motor(salient: bool = False) -> MultiPhaseParameters:
    """The book motor rewound as a dual three-phase machine with the same copper (module docstring)."""
    m = book_motor(salient)
    L_ls3 = THREE_PHASE_LEAKAGE_FRACTION * m.L_d
    return MultiPhaseParameters(
        R=m.R / 2.0,
        L_d=m.L_d / 2.0 - L_ls3 / 4.0,
        L_q=m.L_q / 2.0 - L_ls3 / 4.0,
        psi_f=m.psi_f / 2.0,
        L_ls=L_ls3 / 4.0,
        J=m.J,
        B=m.B,
        pole_pairs=m.pole_pairs,
        n_phases=6,
    )


def load_six_phase_motor(name_or_path) -> MultiPhaseParameters:
    """A six-phase motor by preset name (``book``, ``book_salient``) or from a TOML file with ``R, L_d,
    L_q, psi_f, L_ls, pole_pairs, J, B`` (and optionally ``n_phases = 6``) at top level or under
    ``[motor]``, SI units."""
    key = str(name_or_path)
    if key in ("book", "book_salient"):
        return six_phase_motor(key == "book_salient")
    return read_multiphase_motor_file(name_or_path, 6)


def read_multiphase_motor_file(name_or_path, n_phases: int, optional=()) -> MultiPhaseParameters:
    """An ``n_phases`` motor from a TOML file with `SIX_PHASE_FIELDS` (the n-phase fields, SI units)
    and the keys of `optional` (e.g. ``("psi_f3",)``), at top level or under ``[motor]``; ``n_phases``
    may be given and must match."""
    key = str(name_or_path)
    word = {5: "five", 6: "six"}.get(n_phases, str(n_phases))
    path = Path(name_or_path)
    if not path.is_file():
        raise ParameterError(
            f"{word}-phase motor {key!r} is neither a preset (book, book_salient) nor an existing TOML file."
        )
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as err:
        raise ParameterError(f"motor file {path}: not valid TOML ({err}).") from err
    data = dict(data.get("motor", data))
    n = data.pop("n_phases", n_phases)
    if n != n_phases:
        raise ParameterError(f"motor file {path}: n_phases = {n!r}, a {word}-phase motor needs {n_phases}.")
    missing = [f for f in SIX_PHASE_FIELDS if f not in data]
    if missing:
        raise ParameterError(
            f"motor file {path} lacks {', '.join(missing)}: a {word}-phase motor needs "
            f"{', '.join(SIX_PHASE_FIELDS)} (SI units: ohm, H, H, Wb, H, -, kg m^2, N m s)."
        )
    allowed = SIX_PHASE_FIELDS + tuple(optional)
    unknown = sorted(set(data) - set(allowed))
    if unknown:
        raise ParameterError(
            f"motor file {path}: unknown keys {unknown}; allowed: {', '.join(allowed)}, n_phases."
        )
    if not isinstance(data["pole_pairs"], int):
        raise ParameterError(f"motor file {path}: pole_pairs must be an integer, got {data['pole_pairs']!r}.")
    for f in allowed:
        if f != "pole_pairs" and f in data and not isinstance(data[f], (int, float)):
            raise ParameterError(f"motor file {path}: {f} must be a number, got {data[f]!r}.")
    return MultiPhaseParameters(**{f: data[f] for f in allowed if f in data}, n_phases=n_phases)


#: Machine model frames: ``dq`` (fundamental in the rotor frame, z1-z2 stationary: the fast one), ``vsd``
#: (stationary VSD), ``double-dq``, ``natural`` (6x6 phase inductances).
SIX_PHASE_FRAMES = {
    "dq": MultiPhasePMSMdq,
    "vsd": MultiPhasePMSMVSD,
    "double-dq": PMSM6DoubleDQ,
    "natural": MultiPhasePMSMNatural,
}


def _four_vector():
    return NearFourVectorSVPWM(SIX_PHASE, name="four-vector")


def _two_vector():
    return LargeVectorSVPWM(SIX_PHASE, name="two-vector")


def _double_zs():
    return ZeroSequencePWM(SIX_PHASE, "min-max", name="double-zs")


#: Modulators (the book, ch. 8), name -> constructor: four-vector SVPWM (Zhao & Lipo 1995: the L and ML
#: vectors, z1-z2 average nulled; the n-phase near-four-vector method), two-vector SVPWM (the L vectors
#: only, z1-z2 uncontrolled), decoupled SVPWM (the book's SVPWM on each set) and carrier PWM with one
#: min-max zero sequence per set (the same duties as decoupled SVPWM inside the linear range).
SIX_PHASE_PWMS = {
    "four-vector": _four_vector,
    "two-vector": _two_vector,
    "decoupled": DecoupledSVPWM,
    "double-zs": _double_zs,
}

#: Control schemes by name -> one-line description (`pmsmjax.spec.registry.REGISTRY`).
SIX_PHASE_CONTROLS = machine_controls("six-phase")


def six_phase_machine(motor=None, frame: str = "dq", mechanics: str = "dynamic", resistance_scale=None):
    """The six-phase machine model of ``motor`` in ``frame``
    ([`SIX_PHASE_FRAMES`][pmsmjax.presets.six_phase.SIX_PHASE_FRAMES])."""
    motor = six_phase_motor() if motor is None else motor
    return multiphase_machine("six-phase", SIX_PHASE_FRAMES, motor, frame, mechanics, resistance_scale)


def six_phase_current_block(control: str, motor, current_bandwidth: float, w_c: float = PR_W_C):
    """The six-phase current block of ``control``
    ([`SIX_PHASE_CONTROLS`][pmsmjax.presets.six_phase.SIX_PHASE_CONTROLS]) from the design rules."""
    if control == "vsd":
        return vsd_current_design(motor, current_bandwidth)
    if control == "conventional":
        return VSDCurrentControl(current_loop_imc(motor, current_bandwidth), None)
    if control == "double-dq":
        return double_dq_design(motor, current_bandwidth)
    if control == "pr":
        return pr_current_design(motor, current_bandwidth, w_c)
    raise ParameterError(
        f"six-phase control must be one of {', '.join(SIX_PHASE_CONTROLS)}, got {control!r}."
    )


six_phase_drive = multiphase_drive_function(
    "six_phase_drive",
    __name__,
    """A six-phase drive: `control` ([`SIX_PHASE_CONTROLS`][pmsmjax.presets.six_phase.SIX_PHASE_CONTROLS]),
    `pwm` ([`SIX_PHASE_PWMS`][pmsmjax.presets.six_phase.SIX_PHASE_PWMS]), `bridge` (``averaged`` or
    ``switching``, the latter with optional `dead_time` s), `frame`
    ([`SIX_PHASE_FRAMES`][pmsmjax.presets.six_phase.SIX_PHASE_FRAMES]); the rest as
    [`pmsmjax.presets.book_drive`][pmsmjax.presets.three_phase.book_drive]. `w_c` rad/s: the PR resonators'
    damping; `resistance_scale`: ``(6,)`` phase resistance factors of the plant (unbalance).

    Every control uses the design-rule gains of the same motor (the controller's model is the plant's
    balanced motor): the speed PI with active damping at ``speed_bandwidth``, current loops at
    ``current_bandwidth`` ([`pmsmjax.controllers.multiphase`][pmsmjax.controllers.multiphase]).
    """,
    machine="six-phase",
    layout=SIX_PHASE,
    default_motor=six_phase_motor,
    pwms=SIX_PHASE_PWMS,
    default_pwm="four-vector",
    machine_model=six_phase_machine,
    current_block=six_phase_current_block,
)
