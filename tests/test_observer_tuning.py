"""Gradient tuning of the chapter 5 observers (issue 14, item 4): the tuning objective's gradient w.r.t.
every tunable observer parameter.

Independent reference: central finite differences of the same loss in float64 (tests/conftest.py), at
the design-rule point; and finiteness of the gradient over 1000 random draws of the parameters within a
factor 2 of the design rule (draws the observer's own stability check refuses are redrawn: outside its
linearised stability region the observer is not a candidate). One compiled, vmapped value-and-gradient
per observer evaluates the design point, the 2n finite-difference points and the 1000 draws in one call.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from pmsmjax.estimators import OBSERVERS
from pmsmjax.validation import ParameterError
from tuning.autotune.objectives import ObjectiveWeights, smoothed_batch_cost
from tuning.autotune.observers import (
    TUNABLE_OBSERVERS,
    make_observer_batch,
    observer_drive,
    observer_tuning,
)
from tuning.parameters import LogParameterisation, get_leaf, set_leaves

N_DRAWS = 1000
H = 1e-5  # log-space step of the central differences
# one step and one speed (1200 periods: warm-up 20 ms, step at 40 ms, load step at 66-84 ms)
BATCH = make_observer_batch(1, 3, duration_s=(0.12, 0.12), speed_rpm=(300.0, 1500.0), kinds=("step",))


def test_every_observer_has_a_table_entry():
    assert set(TUNABLE_OBSERVERS) == set(OBSERVERS)


def _stable_draws(drive, param, rng, n):
    """``n`` log-factor draws in [log 1/2, log 2] whose observer passes ``check_period``."""
    draws, refused = [], 0
    while len(draws) < n:
        theta = rng.uniform(np.log(0.5), np.log(2.0), param.p0.shape)
        try:
            param.apply(drive, jnp.asarray(theta)).estimator.check_period(drive.Ts)
        except ParameterError:
            refused += 1
            continue
        draws.append(theta)
    return np.stack(draws), refused


@pytest.mark.parametrize("name", list(OBSERVERS))
def test_gradient_matches_central_differences_and_is_finite_over_draws(name):
    tuning = observer_tuning(name)
    drive = observer_drive(name, n_substeps=1)
    weights = ObjectiveWeights(**tuning.weights)
    param = LogParameterisation(drive, tuning.names, (0.05, 20.0))
    n = len(param.names)

    def loss(theta):
        return smoothed_batch_cost(param.apply(drive, theta), BATCH, weights)[0]

    draws, refused = _stable_draws(drive, param, np.random.default_rng(0), N_DRAWS)
    eye = np.eye(n)
    points = np.concatenate([np.zeros((1, n)), H * eye, -H * eye, draws])
    values, grads = jax.jit(jax.vmap(jax.value_and_grad(loss)))(jnp.asarray(points))
    values, grads = np.asarray(values), np.asarray(grads)

    g = grads[0]
    fd = (values[1 : 1 + n] - values[1 + n : 1 + 2 * n]) / (2 * H)
    rel = np.abs(g - fd) / np.abs(fd)
    assert np.all(rel < 1e-4), (name, dict(zip(param.names, rel, strict=True)), g, fd)
    # every parameter moves the loss (a zero gradient would make the check above vacuous)
    assert np.all(np.abs(g) > 1e-6 * values[0]), (name, g)
    draw_grads = grads[1 + 2 * n :]
    assert np.all(np.isfinite(values[1 + 2 * n :])) and np.all(np.isfinite(draw_grads)), name
    assert refused < N_DRAWS, (name, refused)


def test_vector_leaf_elements_are_named_and_set():
    """EKF Q and R diagonals are tuned element by element (``estimator.observer.q[2]``)."""
    drive = observer_drive("ekf", n_substeps=1)
    q = np.asarray(get_leaf(drive, "estimator.observer.q"))
    assert float(get_leaf(drive, "estimator.observer.q[2]")) == q[2]
    new = set_leaves(drive, ["estimator.observer.q[2]", "estimator.observer.q[0]"], [1.0, 2.0])
    np.testing.assert_array_equal(np.asarray(new.estimator.observer.q), [2.0, q[1], 1.0, q[3]])
