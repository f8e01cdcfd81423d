"""A minimal hand-written closed loop: the yardstick the library's speed is measured against.

Same physics and numerics as the book drive (dq machine held in the stator frame over each period,
RK4 sub-steps, SVPWM limit as a circular voltage limit, speed PI with active damping, dq current PIs
with decoupling, one-period computational delay compensated by predicting the current one period ahead)
written as one flat function with no library abstractions. It records speed and dq currents per period.
"""

import jax
import jax.numpy as jnp

from pmsmjax.presets import book_constants as book

SQRT3 = 3.0**0.5


#: The motor parameters the ``runtime_parameters`` variant takes at run time (the book motor).
BOOK = dict(
    R=book.BOOK_R_OHM, L=book.BOOK_L_H, psi=book.BOOK_PSI_F_WB, J=book.BOOK_J_KG_M2, B=book.BOOK_B_NM_S
)


def make_minimal_loop(
    R=book.BOOK_R_OHM,
    L=book.BOOK_L_H,
    psi=book.BOOK_PSI_F_WB,
    p=book.BOOK_POLE_PAIRS,
    J=book.BOOK_J_KG_M2,
    B=book.BOOK_B_NM_S,
    u_dc=book.BOOK_DC_LINK,
    Ts=book.BOOK_TS,
    n_sub=10,
    a_c=book.BOOK_CURRENT_BANDWIDTH,
    beta=book.BOOK_SPEED_BANDWIDTH,
    i_max=book.BOOK_CURRENT_LIMIT,
    runtime_parameters=False,
):
    """Return ``run(speed_ref (N,), load (N,)) -> (omega (N,), i_dq (N, 2))``, jit-compiled.

    With ``runtime_parameters=True`` the motor parameters are arguments instead of literals:
    ``run(speed_ref, load, params)`` with ``params`` a dict like `BOOK`. A library must take its
    parameters at run time (to vmap and differentiate over them); literals let XLA constant-fold, which
    this variant measures the worth of.
    """
    if runtime_parameters:

        def run_with(speed_ref, load, params):
            loop = _build(p=p, u_dc=u_dc, Ts=Ts, n_sub=n_sub, a_c=a_c, beta=beta, i_max=i_max, **params)
            return loop(speed_ref, load)

        return jax.jit(run_with)
    return jax.jit(_build(R, L, psi, p, J, B, u_dc, Ts, n_sub, a_c, beta, i_max))


def _build(R, L, psi, p, J, B, u_dc, Ts, n_sub, a_c, beta, i_max):
    kt = 1.5 * p * psi
    kp_w, ki_w, b_a = beta * J / kt, beta * beta * J / kt, (beta * J - B) / kt
    kp_i, ki_i = a_c * L, a_c * R
    u_max = u_dc / SQRT3
    h = Ts / n_sub

    def f(x, u_a, u_b, t_l):
        i_d, i_q, w, th = x
        c, s = jnp.cos(th), jnp.sin(th)
        u_d, u_q = u_a * c + u_b * s, -u_a * s + u_b * c
        we = p * w
        return jnp.stack(
            [
                (u_d - R * i_d + we * L * i_q) / L,
                (u_q - R * i_q - we * (L * i_d + psi)) / L,
                (kt * i_q - t_l - B * w) / J,
                we,
            ]
        )

    def period(carry, inp):
        x, xi_w, xi_d, xi_q, u_prev, u_dq_prev = carry
        w_ref, t_l = inp
        i_d0, i_q0, w, th = x
        e = w_ref - w
        v = kp_w * e + xi_w - b_a * w
        iq_ref = jnp.clip(v, -i_max, i_max)
        xi_w = xi_w + Ts * ki_w * e + (iq_ref - v)
        we = p * w
        # Delay compensation: the current one period ahead under the voltage already committed.
        i_d = i_d0 + Ts * (u_dq_prev[0] - R * i_d0 + we * L * i_q0) / L
        i_q = i_q0 + Ts * (u_dq_prev[1] - R * i_q0 - we * (L * i_d0 + psi)) / L
        vd = kp_i * (0.0 - i_d) + xi_d - we * L * i_q
        vq = kp_i * (iq_ref - i_q) + xi_q + we * (L * i_d + psi)
        mag = jnp.sqrt(vd * vd + vq * vq)
        k = jnp.where(mag > u_max, u_max / mag, 1.0)
        ud, uq = vd * k, vq * k
        xi_d = xi_d + Ts * ki_i * (0.0 - i_d) + (ud - vd)
        xi_q = xi_q + Ts * ki_i * (iq_ref - i_q) + (uq - vq)
        th_c = th + we * 1.5 * Ts
        u_new = jnp.stack([ud * jnp.cos(th_c) - uq * jnp.sin(th_c), ud * jnp.sin(th_c) + uq * jnp.cos(th_c)])
        u_a, u_b = u_prev[0], u_prev[1]

        def rk4(_, x):
            k1 = f(x, u_a, u_b, t_l)
            k2 = f(x + 0.5 * h * k1, u_a, u_b, t_l)
            k3 = f(x + 0.5 * h * k2, u_a, u_b, t_l)
            k4 = f(x + h * k3, u_a, u_b, t_l)
            return x + (h / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)

        # fori_loop, not a Python loop: XLA:CPU compiles an unrolled RK4 chain into far slower code.
        x = jax.lax.fori_loop(0, n_sub, rk4, x)
        x = x.at[3].set(jnp.mod(x[3] + jnp.pi, 2 * jnp.pi) - jnp.pi)
        return (x, xi_w, xi_d, xi_q, u_new, jnp.stack([ud, uq])), (w, jnp.stack([i_d0, i_q0]))

    def run(speed_ref, load):
        dtype = speed_ref.dtype
        z = jnp.zeros((), dtype)
        carry = (jnp.zeros(4, dtype), z, z, z, jnp.zeros(2, dtype), jnp.zeros(2, dtype))
        _, (w, i_dq) = jax.lax.scan(period, carry, (speed_ref, load))
        return w, i_dq

    return run
