"""Step-capped BFGS with backtracking, asked for one cost-and-gradient evaluation at a time.

Why not Adam or scipy's L-BFGS-B for tuning gains: Adam needs hundreds of gradients on this cost
(its step size is a guess, and the design-rule start is far from the optimum in some gains); L-BFGS-B
takes quasi-Newton steps of any length, so early on it tries gains 10-20x off (costs 20-30x the
current one, every other evaluation wasted) and it stalls at the kinks of the L1 constraint
penalties. Here every trial step is capped in log-space (``max_step`` = 0.5: no gain moves by more
than a factor e^0.5 = 1.65 per step), a trial that does not decrease the cost enough (Armijo) is
retried at 0.3x the step, and after ``max_tries`` failures along one direction the curvature estimate
is dropped and the cap shrinks to the last step tried (steepest descent again, from there: restarting
at the full cap would repeat the same failed trials forever); a full-length accepted step doubles the
cap again, up to ``max_step``. Used with the rounded penalties of
[`tuning.autotune.objectives.smoothed_penalty`][tuning.autotune.objectives.smoothed_penalty], whose kinks are
what stalls a quasi-Newton method.

**Ask-tell.** [`bfgs_tell`][tuning.autotune.quasi_newton.bfgs_tell] takes the evaluation at the point it asked
for last and returns the next point to evaluate, so the tuner's loop, progress bar and checkpoints stay the
same as for Adam. The state is a tuple of float64 NumPy arrays (exact in a checkpoint); the inverse-Hessian
estimate is updated from every evaluated pair with positive curvature, accepted or not.
"""

from typing import NamedTuple

import numpy as np

__all__ = ["BFGSState", "bfgs_init", "bfgs_tell"]

ARMIJO = 1e-4  # sufficient-decrease constant
BACKTRACK = 0.3  # step factor after a failed trial


class BFGSState(NamedTuple):
    """``x, f, g``: the accepted point ``(n,)``, its cost (inf before the first) and gradient;
    ``H (n, n)``: inverse-Hessian estimate (all zero: none yet); ``d (n,)``: the search direction;
    ``alpha``: the fraction of ``d`` being tried; ``tries``: failed trials along ``d``; ``radius``: the
    current cap on the largest component of a step (log-space)."""

    x: np.ndarray
    f: np.ndarray
    g: np.ndarray
    H: np.ndarray
    d: np.ndarray
    alpha: np.ndarray
    tries: np.ndarray
    radius: np.ndarray


def bfgs_init(n: int, max_step: float = 0.5) -> BFGSState:
    """The state before any evaluation (the first evaluation is accepted as it is)."""
    z = np.zeros(n)
    one = np.array(1.0)
    return BFGSState(z, np.array(np.inf), z, np.zeros((n, n)), z, one, np.array(0), one * max_step)


def _direction(H, g, x, lower, upper, max_step):
    """Quasi-Newton (or capped steepest) descent direction, with coordinates that would leave the box
    at an active bound dropped, and scaled so its largest component is at most ``max_step``."""
    d = -(H @ g) if np.any(H) else -g
    if not g @ d < 0:  # not a descent direction: fall back on steepest descent
        d = -g
    blocked = ((x <= lower) & (d < 0)) | ((x >= upper) & (d > 0))
    d = np.where(blocked, 0.0, d)
    big = np.max(np.abs(d))
    if big == 0:
        return d
    if not np.any(H) or big > max_step:
        d = d * (max_step / big)
    return d


def bfgs_tell(state: BFGSState, theta, cost, grad, *, lower: float, upper: float, max_step: float = 0.5,
              max_tries: int = 3) -> tuple[np.ndarray, BFGSState]:  # fmt: skip
    """Take the evaluation ``(cost, grad (n,))`` at ``theta (n,)`` (the point asked for last, or the
    start); return the next point to evaluate, inside ``[lower, upper]``, and the new state.

    A non-finite cost counts as a failed trial (gains that destabilise the drive on some scenario).
    """
    theta, grad = np.asarray(theta, np.float64), np.asarray(grad, np.float64)
    cost = float(cost)
    x, f, g, H, d, alpha, tries, radius = state
    radius = min(float(radius), max_step)
    if not np.isfinite(f):  # the first evaluation
        if not (np.isfinite(cost) and np.all(np.isfinite(grad))):
            raise ValueError("the starting point has a non-finite cost or gradient")
        x, f, g = theta, np.array(cost), grad
        d = _direction(H, g, x, lower, upper, radius)
        alpha, tries = 1.0, 0
    else:
        ok = np.isfinite(cost) and np.all(np.isfinite(grad))
        s, y = theta - x, grad - g
        sy = float(s @ y) if ok else 0.0
        if ok and sy > 1e-10 * np.linalg.norm(s) * np.linalg.norm(y):
            if not np.any(H):
                H = np.eye(x.size) * sy / float(y @ y)
            rho = 1.0 / sy
            V = np.eye(x.size) - rho * np.outer(s, y)
            H = V @ H @ V.T + rho * np.outer(s, s)
        if ok and cost <= float(f) + ARMIJO * float(g @ s):
            if float(alpha) == 1.0 and np.max(np.abs(s)) >= 0.99 * radius:
                radius = min(2.0 * radius, max_step)
            x, f, g = theta, np.array(cost), grad
            d = _direction(H, g, x, lower, upper, radius)
            alpha, tries = 1.0, 0
        elif int(tries) + 1 >= max_tries:
            H = np.zeros_like(H)
            radius = max(BACKTRACK * float(alpha) * float(np.max(np.abs(d))), 1e-12)
            d = _direction(H, g, x, lower, upper, radius)
            alpha, tries = 1.0, 0
        else:
            alpha, tries = float(alpha) * BACKTRACK, int(tries) + 1
    new = BFGSState(x, np.asarray(f, np.float64), g, H, d, np.array(float(alpha)), np.array(int(tries)),
                    np.array(radius))  # fmt: skip
    return np.clip(x + alpha * d, lower, upper), new
