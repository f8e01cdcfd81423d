"""The gradient check itself (tests/helpers/gradient_check.py), on closed forms whose derivatives are known:
it passes a right gradient, fails a wrong one naming the scalar, and its stacked points give the same
quotients as point-by-point evaluation."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from helpers.gradient_check import CentralDifferences, assert_gradient_close, check_gradient


class Gains(eqx.Module):
    kp: jax.Array
    q: jax.Array
    order: int  # not a float: never stepped


def cost(g: Gains):
    """kp^3 + sum(exp(q)) (times 1 for order 1): gradient (3 kp^2, exp(q))."""
    return g.order * (g.kp**3 + jnp.sum(jnp.exp(g.q)))


GAINS = Gains(jnp.asarray(0.7), jnp.array([0.0, -1.5, 2.0]), 1)


def test_a_right_gradient_passes_and_the_figures_are_returned():
    r = check_gradient(jax.jit(cost), GAINS, rtol=1e-8)
    assert r.names == ("kp", "q[0]", "q[1]", "q[2]")
    np.testing.assert_allclose(r.grad, [3 * 0.49, 1.0, np.exp(-1.5), np.exp(2.0)], rtol=1e-14)
    np.testing.assert_allclose(r.fd, r.grad, rtol=1e-8)
    assert r.value == pytest.approx(0.343 + 1 + np.exp(-1.5) + np.exp(2.0), rel=1e-14)


def test_a_wrong_gradient_fails_naming_the_scalar():
    wrong = eqx.tree_at(lambda g: g.q, GAINS, jnp.array([1.0, np.exp(-1.5), 1.01 * np.exp(2.0)]))
    wrong = eqx.tree_at(lambda g: g.kp, wrong, jnp.asarray(3 * 0.49))
    with pytest.raises(AssertionError, match=r"for 1 of 4:\n  q\[2\]: x = 2, gradient 7.46"):
        check_gradient(cost, GAINS, grad=wrong, rtol=1e-4)
    with pytest.raises(AssertionError, match="kp"):  # a non-finite gradient never passes
        assert_gradient_close([np.nan], [1.0], names=["kp"], x=[1.0], rtol=1.0, atol=1.0)


def test_select_richardson_and_stacked_points():
    """Only the selected leaf is stepped; Richardson removes the h^2 term (exact for a cubic); the stacked
    points of one vmapped call give the same quotients as one call per point."""
    stencil = CentralDifferences.around(GAINS, rel_step=1e-2, select={"kp"}, richardson=True)
    assert stencil.names == ("kp",) and stencil.size == 4
    fd = stencil.quotients(stencil.evaluate(cost))
    assert fd[0] == pytest.approx(3 * 0.49, rel=1e-12)  # a 1e-2 step, yet exact to rounding
    plain = CentralDifferences.around({"a": 0.3, "b": jnp.array([1.0, 2.0])}, rel_step=1e-5, step_floor=0.0)
    f = lambda p: p["a"] ** 2 * jnp.sum(jnp.sin(p["b"]))
    batched = plain.quotients(jax.vmap(f)(plain.points()))
    np.testing.assert_allclose(batched, plain.quotients(plain.evaluate(f)), rtol=1e-12)
    np.testing.assert_allclose(plain.steps, 1e-5 * np.array([0.3, 1.0, 2.0]))
    with pytest.raises(ValueError, match="float64"):
        CentralDifferences.around(jnp.array([1.0], dtype=jnp.float32))
    with pytest.raises(ValueError, match="step_floor"):
        CentralDifferences.around(0.0, step_floor=0.0)
