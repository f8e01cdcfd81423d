"""Design rules of the six- and five-phase current blocks (the book, ch. 9 and 10): the second plane's PI
(internal-model design), the VSD and double-dq current controllers at a bandwidth, and the
proportional-resonant blocks."""

import jax.numpy as jnp

from pmsmjax.controllers.design import current_loop_imc
from pmsmjax.controllers.multiphase import (
    DoubleDQCurrentPI,
    VSDCurrentControl,
    ZCurrentPI,
    ZProportionalResonant,
)
from pmsmjax.controllers.pr import (
    ProportionalResonant,
    pr_design,
)
from pmsmjax.frames.multiphase import (
    SIX_PHASE,
    PhaseLayout,
)
from pmsmjax.spec.validation import check_positive


def z_current_imc(
    motor, bandwidth_rad_s=1100.0, z_limit_fraction: float = 0.2, rotation: int = -1
) -> ZCurrentPI:
    """Internal-model z1-z2 (or x-y) PI: ``Kp = a_z L_ls``, ``Ki = a_z R`` (closed loop ``a_z/(s + a_z)``
    with the decoupling, as the dq loop), in the frame at ``rotation theta_e``."""
    check_positive("z-loop bandwidth a_z", bandwidth_rad_s, "rad/s")
    a = jnp.asarray(bandwidth_rad_s, motor.R.dtype)
    return ZCurrentPI(a * motor.L_ls, a * motor.R, z_limit_fraction, rotation)


def vsd_current_design(
    motor,
    bandwidth_rad_s=1100.0,
    z_bandwidth_rad_s=None,
    z: bool = True,
    layout: PhaseLayout = SIX_PHASE,
    rotation: int = -1,
):
    """VSD current control from the internal-model rules: the dq PI
    ([`current_loop_imc`][pmsmjax.controllers.design.current_loop_imc]) and, with ``z=True``, the second
    plane's PI ([`z_current_imc`][pmsmjax.controllers.multiphase_design.z_current_imc], bandwidth default
    the dq loop's, frame at ``rotation theta_e``); ``z=False`` is the conventional scheme. `layout`: the
    winding (five phases: [`FIVE_PHASE`][pmsmjax.frames.multiphase.FIVE_PHASE] with ``rotation=3``)."""
    z_block = z_current_imc(motor, z_bandwidth_rad_s or bandwidth_rad_s, rotation=rotation) if z else None
    return VSDCurrentControl(current_loop_imc(motor, bandwidth_rad_s), z_block, layout)


def double_dq_design(motor, bandwidth_rad_s=1100.0, cross_coupling: bool = True) -> DoubleDQCurrentPI:
    """Double-dq PIs designed equivalently to
    [`vsd_current_design`][pmsmjax.controllers.multiphase_design.vsd_current_design] at the same
    bandwidth ``a_c`` (book 9.5): self gains ``Kp = a_c (L + L_ls)/2`` (the set's own inductance),
    ``Ki = a_c R``; cross-coupling ``kc = a_c (L - L_ls)/2`` (``a_c`` times the mutual inductance), or 0
    without it."""
    check_positive("current-loop bandwidth a_c", bandwidth_rad_s, "rad/s")
    a = jnp.asarray(bandwidth_rad_s, motor.R.dtype)
    k = 1.0 if cross_coupling else 0.0
    return DoubleDQCurrentPI(
        kp_d=a * 0.5 * (motor.L_d + motor.L_ls),
        kp_q=a * 0.5 * (motor.L_q + motor.L_ls),
        ki_d=a * motor.R,
        ki_q=a * motor.R,
        kc_d=k * a * 0.5 * (motor.L_d - motor.L_ls),
        kc_q=k * a * 0.5 * (motor.L_q - motor.L_ls),
    )


def z_pr_design(motor, bandwidth_rad_s=1100.0, w_c=2.0, **options) -> ZProportionalResonant:
    """z1-z2 PR equivalent to the z1-z2 PI of bandwidth ``a_z``: ``Kp = a_z L_ls``, ``Kr w_c = a_z R``
    (as [`pmsmjax.controllers.pr.pr_design`][pmsmjax.controllers.pr.pr_design])."""
    check_positive("z-loop bandwidth a_z", bandwidth_rad_s, "rad/s")
    check_positive("resonator damping w_c", w_c, "rad/s")
    a = jnp.asarray(bandwidth_rad_s, motor.R.dtype)
    w_c = jnp.asarray(w_c, motor.R.dtype)
    return ZProportionalResonant(a * motor.L_ls, a * motor.R / w_c, w_c, **options)


def pr_current_design(motor, bandwidth_rad_s=1100.0, w_c=2.0, **options) -> VSDCurrentControl:
    """Stationary-frame PR for six phases: the alpha-beta PR ([`pr_design`][pmsmjax.controllers.pr.pr_design])
    and the z1-z2 PR ([`z_pr_design`][pmsmjax.controllers.multiphase_design.z_pr_design]) at the same
    bandwidth and damping; ``options`` go to the alpha-beta PR (``discretisation``, ``phase_lead``,
    ``back_emf_feedforward``), the first two to the z1-z2 PR too."""
    dq: ProportionalResonant = pr_design(motor, bandwidth_rad_s, w_c, **options)
    z_options = {k: v for k, v in options.items() if k in ("discretisation", "phase_lead")}
    return VSDCurrentControl(dq, z_pr_design(motor, bandwidth_rad_s, w_c, **z_options))
