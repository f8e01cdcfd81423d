"""A gradient against central finite differences, in float64: the one check every gradient test makes.

For a scalar function ``f`` of a pytree ``x`` (a float, an array, a dict of gains, an equinox module) each
checked scalar ``x_k`` is stepped both ways and the difference quotient

    d_k = (f(x + h_k e_k) - f(x - h_k e_k)) / (2 h_k)

is compared with the gradient's entry ``g_k``: the check passes where ``|g_k - d_k| <= rtol |d_k| + atol``
(and ``g_k`` is finite). Optionally the quotients at ``h`` and ``h/2`` are Richardson-combined,
``(4 d(h/2) - d(h)) / 3``, which removes the ``h^2`` term of the truncation error.

Step: ``h_k = rel_step * max(|x_k|, step_floor)``. The truncation error of the quotient is about
``h^2 f''' / 6`` and its round-off about ``eps_f |f| / h`` (``eps_f`` is the relative rounding of ``f``,
1e-16 for a closed form, 1e-14 or more after thousands of scan steps): a test picks ``rel_step`` where the
two balance for its ``f``. ``step_floor = 0`` makes the step purely relative (physical parameters of any
magnitude: an inductance of 5e-3 H is stepped by ``rel_step`` of itself); the default 1 keeps the step
from vanishing at ``x_k = 0`` (log-space factors, whose design point is 0). The step actually taken is
``(x + h) - (x - h)`` as rounded in float64, and the quotient divides by that.

Two ways to evaluate ``f`` at the points:

- :func:`check_gradient` calls ``f`` once per point (pass a jit-compiled ``f``);
- :class:`CentralDifferences` gives the points stacked along a leading axis, for one vmapped call that can
  carry other points too (random draws), and turns the values back into quotients.

Only float64 is accepted: in float32 the round-off term alone exceeds the usual 1e-4 tolerance.
"""

import dataclasses
from collections.abc import Callable, Collection, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["CentralDifferences", "GradientCheck", "assert_gradient_close", "check_gradient", "leaf_name"]


def leaf_name(path) -> str:
    """Dotted name of a pytree path: ``controller.speed.kp`` (attributes), ``kp`` (dict keys), ``q[2]``."""
    name = ""
    for key in path:
        if isinstance(key, jax.tree_util.SequenceKey):
            name += f"[{key.idx}]"
        else:
            part = key.name if isinstance(key, jax.tree_util.GetAttrKey) else getattr(key, "key", key)
            name += f".{part}" if name else str(part)
    return name


def _selector(select) -> Callable[[str], bool]:
    if select is None:
        return lambda name: True
    if callable(select):
        return select
    wanted = set(select)
    return lambda name: name in wanted


def _with_value(leaf, index, value):
    """``leaf`` with element ``index`` set to ``value``, of the leaf's own type (a Python float stays one,
    a JAX array keeps its dtype and weak type: a jit-compiled ``f`` sees the same signature and is not
    compiled again)."""
    if isinstance(leaf, float):
        return float(value)
    if isinstance(leaf, jax.Array):
        return leaf.at[index].set(value)
    out = np.array(leaf, dtype=np.float64)
    out[index] = value
    return out


@dataclasses.dataclass(frozen=True)
class CentralDifferences:
    """The points where a central-difference check evaluates ``f``, and the quotients from the values.

    Build it with :meth:`around`. Attributes, one entry per checked scalar (``n`` of them):

    - `names`: ``(n,)`` leaf name with the element index for array leaves (``estimator.observer.q[2]``),
      or the labels given to :meth:`around`;
    - `x`: ``(n,)`` the scalars' values; `steps`: ``(n,)`` the step ``h`` of each.

    The points come in the order ``x + h e_k`` for every k, then ``x - h e_k``; with Richardson
    extrapolation then the same at ``h/2``: ``size`` = 2n or 4n points.
    """

    names: tuple[str, ...]
    x: np.ndarray
    steps: np.ndarray
    richardson: bool
    _tree: object
    _leaves: tuple
    _leaf_names: tuple
    _slots: tuple  # (leaf number, index in the leaf) of each checked scalar

    @classmethod
    def around(
        cls,
        x,
        *,
        rel_step: float = 1e-6,
        step_floor: float = 1.0,
        select: Collection[str] | Callable[[str], bool] | None = None,
        labels: Sequence[str] | None = None,
        richardson: bool = False,
    ) -> "CentralDifferences":
        """The stencil around ``x``: every floating-point scalar of every selected leaf.

        **Arguments:**

        - `x`: the point, a pytree of floats and float64 arrays (other leaves are left alone).
        - `rel_step`, `step_floor`: the step ``h = rel_step * max(|x_k|, step_floor)`` (module docstring).
        - `select`: the leaves to check, by name (a collection of :func:`leaf_name` names, or a predicate
          on the name); default every floating-point leaf.
        - `labels`: names for the checked scalars in failure messages (e.g. the tuner's parameter names
          of a flat vector), in place of the leaf names.
        - `richardson`: also step by ``h/2`` and Richardson-combine the two quotients.
        """
        if not jax.config.jax_enable_x64:
            raise ValueError("central differences need float64: enable jax_enable_x64 (tests/conftest.py).")
        with_paths, tree = jax.tree_util.tree_flatten_with_path(x)
        wanted = _selector(select)
        leaves = tuple(leaf for _, leaf in with_paths)
        leaf_names = tuple(leaf_name(path) for path, _ in with_paths)
        names, values, slots = [], [], []
        for number, (name, leaf) in enumerate(zip(leaf_names, leaves, strict=True)):
            if not (eqx.is_inexact_array_like(leaf) and wanted(name)):
                continue
            array = np.asarray(leaf)
            if array.dtype != np.float64:
                raise ValueError(f"leaf {name!r} is {array.dtype}: central differences need float64 leaves.")
            for index in np.ndindex(array.shape):
                names.append(name + "".join(f"[{i}]" for i in index))
                values.append(float(array[index]))
                slots.append((number, index))
        if not names:
            raise ValueError("no floating-point leaf of x is selected: nothing to check.")
        if labels is not None:
            if len(labels) != len(names):
                raise ValueError(f"{len(labels)} labels for {len(names)} checked scalars ({names}).")
            names = list(labels)
        x_k = np.asarray(values)
        steps = rel_step * np.maximum(np.abs(x_k), step_floor)
        if not np.all(steps > 0):
            zero = [n for n, h in zip(names, steps, strict=True) if not h > 0]
            raise ValueError(f"zero step for {zero}: give step_floor > 0 for scalars that are 0.")
        return cls(tuple(names), x_k, steps, richardson, tree, leaves, leaf_names, tuple(slots))

    @property
    def n(self) -> int:
        """Number of checked scalars."""
        return len(self.names)

    @property
    def size(self) -> int:
        """Number of evaluation points: 2n, or 4n with Richardson extrapolation."""
        return (4 if self.richardson else 2) * self.n

    def _offsets(self) -> list[tuple[int, float]]:
        """(scalar k, value of x_k) of every point, in the documented order."""
        scales = (1.0, 0.5) if self.richardson else (1.0,)
        return [
            (k, self.x[k] + sign * scale * self.steps[k])
            for scale in scales
            for sign in (1.0, -1.0)
            for k in range(self.n)
        ]

    def each_point(self) -> list:
        """The points as pytrees shaped like ``x``, one per evaluation (``size`` of them)."""
        points = []
        for k, value in self._offsets():
            number, index = self._slots[k]
            leaves = list(self._leaves)
            leaves[number] = _with_value(leaves[number], index, value)
            points.append(jax.tree_util.tree_unflatten(self._tree, leaves))
        return points

    def points(self):
        """The points stacked along a new leading axis of every leaf (``(size, ...)``), for a vmapped
        evaluation; every leaf of ``x`` must then be an array or a float."""
        return jax.tree.map(lambda *leaf: jnp.stack([jnp.asarray(v) for v in leaf]), *self.each_point())

    def evaluate(self, f: Callable) -> np.ndarray:
        """``(size,)`` values of ``f`` at the points, one call each (pass a jit-compiled ``f``)."""
        return np.array([float(f(p)) for p in self.each_point()])

    def quotients(self, values) -> np.ndarray:
        """``(n,)`` central differences from the ``(size,)`` values at the points."""
        values = np.asarray(values, dtype=np.float64)
        if values.shape != (self.size,):
            raise ValueError(f"expected {self.size} values (the points, in order), got {values.shape}.")
        offsets = np.array([v for _, v in self._offsets()])
        n = self.n
        # divide by the step actually taken, (x + h) - (x - h) as rounded, not by 2h
        quotient = lambda v, o: (v[:n] - v[n:]) / (o[:n] - o[n:])
        coarse = quotient(values[: 2 * n], offsets[: 2 * n])
        if not self.richardson:
            return coarse
        fine = quotient(values[2 * n :], offsets[2 * n :])
        return (4.0 * fine - coarse) / 3.0

    def pick(self, grad) -> np.ndarray:
        """``(n,)`` the checked scalars' entries of a gradient pytree shaped like ``x`` (``jax.grad``'s)."""
        by_name = {leaf_name(p): leaf for p, leaf in jax.tree_util.tree_flatten_with_path(grad)[0]}
        out = []
        for number, index in self._slots:
            name = self._leaf_names[number]
            if name not in by_name:
                raise ValueError(f"the gradient has no leaf {name!r} (it must be shaped like x).")
            out.append(float(np.asarray(by_name[name])[index]))
        return np.asarray(out)


def assert_gradient_close(grad, fd, *, names, x, rtol: float, atol=0.0, value=None) -> None:
    """Assert ``|grad - fd| <= rtol |fd| + atol`` and ``grad`` finite, scalar by scalar.

    `grad`, `fd`, `x`: ``(n,)`` gradient entries, central differences and the scalars' values; `names`:
    ``(n,)`` their names; `atol`: a float or ``(n,)``; `value`: ``f(x)``, shown in the message. The
    message names every failing scalar with its value, gradient, difference quotient and their gap.
    """
    grad, fd, x = (np.asarray(a, dtype=np.float64) for a in (grad, fd, x))
    allowed = rtol * np.abs(fd) + np.broadcast_to(np.asarray(atol, dtype=np.float64), fd.shape)
    gap = np.abs(grad - fd)
    bad = ~(np.isfinite(grad) & np.isfinite(fd) & (gap <= allowed))
    if not bad.any():
        return
    lines = [
        f"  {names[k]}: x = {x[k]:.9g}, gradient {grad[k]:.9e}, central difference {fd[k]:.9e}, "
        f"|gradient - difference| {gap[k]:.3e} > {allowed[k]:.3e} allowed"
        for k in np.flatnonzero(bad)
    ]
    at = "" if value is None else f" at f = {float(value):.9e}"
    raise AssertionError(
        f"gradient differs from central differences{at} (rtol {rtol:g}) for {bad.sum()} of {bad.size}:\n"
        + "\n".join(lines)
    )


@dataclasses.dataclass(frozen=True)
class GradientCheck:
    """Outcome of :func:`check_gradient`, for a test's further assertions: ``(n,)`` arrays per scalar."""

    names: tuple[str, ...]
    x: np.ndarray
    grad: np.ndarray
    fd: np.ndarray
    value: float

    @property
    def sensitivity(self) -> np.ndarray:
        """``|x_k g_k| / |f|``: relative change of ``f`` per relative change of ``x_k`` (unit-free)."""
        return np.abs(self.x * self.grad) / abs(self.value)


def check_gradient(
    f: Callable,
    x,
    *,
    grad=None,
    rtol: float,
    atol=0.0,
    rel_step: float = 1e-6,
    step_floor: float = 1.0,
    select: Collection[str] | Callable[[str], bool] | None = None,
    labels: Sequence[str] | None = None,
    richardson: bool = False,
) -> GradientCheck:
    """Check the gradient of the scalar ``f`` at ``x`` against central differences; return the figures.

    **Arguments:**

    - `f`: ``x -> scalar``, evaluated once at ``x`` and once per point (pass it jit-compiled).
    - `x`: the point (a pytree: float, array, dict, equinox module).
    - `grad`: the gradient at ``x``, shaped like ``x``, when the test has it already (from a vmapped
      ``value_and_grad``, say); default ``jax.grad`` of ``f`` with respect to the floating-point leaves.
    - `rtol`, `atol`: the criterion ``|g - d| <= rtol |d| + atol`` (`atol` a float or one per scalar).
    - `rel_step`, `step_floor`, `select`, `labels`, `richardson`: as :meth:`CentralDifferences.around`.

    Raises AssertionError naming each scalar that fails.
    """
    stencil = CentralDifferences.around(
        x, rel_step=rel_step, step_floor=step_floor, select=select, labels=labels, richardson=richardson
    )
    if grad is None:
        params, rest = eqx.partition(x, eqx.is_inexact_array_like)
        grad = jax.grad(lambda p: f(eqx.combine(p, rest)))(params)
    value = float(f(x))
    result = GradientCheck(
        stencil.names, stencil.x, stencil.pick(grad), stencil.quotients(stencil.evaluate(f)), value
    )
    assert_gradient_close(
        result.grad, result.fd, names=result.names, x=result.x, rtol=rtol, atol=atol, value=value
    )
    return result
