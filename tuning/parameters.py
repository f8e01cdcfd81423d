"""Selecting a drive's tunable array leaves by name, their positive parameterisation, and gains files.

Names are dotted attribute paths from the drive, e.g. ``controller.speed.kp``; an element of a vector leaf
is named with its index, e.g. ``estimator.observer.q[2]`` (the EKF's speed process noise). Tuning works on
``theta = log(p / p0)``: every gain stays positive, all parameters are on the same scale whatever their
units, and theta = 0 is the starting point (the design-rule gains). Bounds are factors on ``p0``.
"""

import math
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from pmsmjax.assemble import with_parts
from pmsmjax.drive import Drive
from pmsmjax.io.logs import atomic_write
from pmsmjax.io.toml_parser import read_toml
from pmsmjax.spec.validation import ParameterError

SPEED_GAINS = ("controller.speed.kp", "controller.speed.ki", "controller.speed.active_damping")
CURRENT_GAINS = (
    "controller.current.kp_d",
    "controller.current.kp_q",
    "controller.current.ki_d",
    "controller.current.ki_q",
)
SMC_GAINS = ("controller.speed.c", "controller.speed.eps", "controller.speed.q")
PR_GAINS = ("controller.current.kp", "controller.current.kr", "controller.current.w_c")
SMC_DTC_GAINS = (
    "controller.torque_gain_v",
    "controller.torque_boundary_nm",
    "controller.flux_gain_v",
    "controller.flux_boundary_wb",
)
ALIASES = {
    "speed": SPEED_GAINS,
    "current": CURRENT_GAINS,
    "smc": SMC_GAINS,
    "pr": PR_GAINS,
    "smc_dtc": SMC_DTC_GAINS,
}


def _split_index(name: str) -> tuple[str, int | None]:
    """``"a.b[2]"`` -> ``("a.b", 2)``; ``"a.b"`` -> ``("a.b", None)``."""
    if name.endswith("]") and "[" in name:
        path, index = name[:-1].rsplit("[", 1)
        if index.isdigit():
            return path, int(index)
    return name, None


def get_leaf(tree, name: str):
    """The node of ``tree`` (a drive, or any equinox pytree) at the dotted path ``name`` (e.g.
    ``controller.speed.kp``), or the element of a vector leaf (``estimator.observer.q[2]``)."""
    path, index = _split_index(name)
    node = tree
    for part in path.split("."):
        node = getattr(node, part)
    return node if index is None else node[index]


def set_leaves(tree, names, values):
    """``tree`` with the nodes at the dotted paths ``names`` set to ``values`` (traceable).

    ``tree`` is any equinox pytree: a drive, its state, a data module. A name is a leaf
    (``controller.speed.kp``), a vector leaf's element (``estimator.observer.q[2]``) or a whole block
    (``estimator``, ``machine``, ``bridge.voltage_error``, also where it is ``None``). The rest of ``tree``
    is kept as it is, leaf for leaf: nothing is converted (a whole bridge is checked at the drive's period).
    The only place tuning writes into a pytree, through [`with_parts`][pmsmjax.assemble.with_parts]."""
    updates: dict[str, object] = {}
    for name, value in zip(names, values, strict=True):
        path, index = _split_index(name)
        if index is None:
            updates[path] = value
        else:
            leaf = updates.get(path, get_leaf(tree, path))
            updates[path] = jnp.asarray(leaf).at[index].set(value)
    return with_parts(tree, updates)


def array_leaf_names(drive: Drive) -> list[str]:
    """Dotted names of every scalar floating-point array leaf of ``drive``, and ``name[i]`` for each
    element of a vector (1-D) one."""
    names = []
    for path, leaf in jax.tree_util.tree_flatten_with_path(drive)[0]:
        if eqx.is_inexact_array(leaf) and leaf.ndim <= 1:
            name = ".".join(str(getattr(k, "name", k)) for k in path)
            names.extend([name] if leaf.ndim == 0 else [f"{name}[{i}]" for i in range(leaf.shape[0])])
    return names


def resolve_names(drive: Drive, names) -> tuple[str, ...]:
    """Expand aliases (``speed``, ``current``, ``smc``, ``pr``, ``smc_dtc``) and check every name is a
    positive scalar leaf."""
    if isinstance(names, str):
        names = [names]
    expanded = []
    for n in names:
        expanded.extend(ALIASES.get(n, (n,)))
    if not expanded:
        raise ParameterError("no gains selected: name at least one, e.g. 'speed' or 'controller.speed.kp'.")
    available = array_leaf_names(drive)
    for n in expanded:
        if n not in available:
            raise ParameterError(
                f"unknown gain name {n!r}: choose from the aliases {sorted(ALIASES)} or the drive's array "
                f"leaves {available}."
            )
        if not float(get_leaf(drive, n)) > 0:
            raise ParameterError(
                f"{n} = {float(get_leaf(drive, n))} is not positive: tuning works on log(p/p0) and needs a "
                "positive starting value."
            )
    if len(set(expanded)) != len(expanded):
        raise ParameterError(f"gain names repeat: {expanded}.")
    return tuple(expanded)


class LogParameterisation(eqx.Module):
    """``p = p0 exp(theta)`` for the named leaves; ``theta`` clipped to ``[log lower, log upper]``."""

    names: tuple[str, ...] = eqx.field(static=True)
    p0: jnp.ndarray  # (n,) starting values
    log_lower: float = eqx.field(static=True)
    log_upper: float = eqx.field(static=True)

    def __init__(self, drive: Drive, names, bounds=(0.05, 20.0)):
        lower, upper = bounds
        if not (np.isfinite(lower) and np.isfinite(upper) and 0 < lower <= 1 <= upper):
            raise ParameterError(
                f"bounds are factors on the starting gains and need 0 < lower <= 1 <= upper, got {bounds}."
            )
        self.names = resolve_names(drive, names)
        self.p0 = jnp.stack([jnp.asarray(get_leaf(drive, n)) for n in self.names])
        self.log_lower, self.log_upper = math.log(lower), math.log(upper)

    def initial_theta(self) -> jnp.ndarray:
        """The starting point, ``theta = 0`` (every leaf at its starting value ``p0``)."""
        return jnp.zeros_like(self.p0)

    def project(self, theta):
        """``theta`` clipped to ``[log lower, log upper]``, the bounds as factors on ``p0``."""
        return jnp.clip(theta, self.log_lower, self.log_upper)

    def values(self, theta) -> jnp.ndarray:
        """The leaves' values ``p0 exp(theta)``, shape ``(n,)``."""
        return self.p0 * jnp.exp(theta)

    def apply(self, drive: Drive, theta) -> Drive:
        """``drive`` with the named leaves set to ``p0 exp(theta)``."""
        p = self.values(theta)
        return set_leaves(drive, self.names, [p[i] for i in range(len(self.names))])


def write_gains_toml(path, names, values, header: str = "") -> Path:
    """Write ``[gains]`` with one ``"dotted.name" = value`` per line, atomically."""
    lines = [f"# {line}" for line in header.splitlines()] + ["[gains]"]
    lines += [f'"{n}" = {float(v)!r}' for n, v in zip(names, values, strict=True)]
    text = "\n".join(lines) + "\n"
    return atomic_write(path, lambda f: f.write(text.encode()))


def read_gains_toml(path) -> dict[str, float]:
    """The ``[gains]`` table of a gains file (as [`write_gains_toml`][tuning.parameters.write_gains_toml]
    writes it), name -> value; a missing file or table raises ``ParameterError``."""
    path = Path(path)
    if not path.is_file():
        raise ParameterError(f"gains file {path} does not exist.")
    data = read_toml(path, f"gains file {path}")
    if "gains" not in data or not isinstance(data["gains"], dict):
        raise ParameterError(f"gains file {path} has no [gains] table.")
    return {k: float(v) for k, v in data["gains"].items()}


#: A gain more than this factor away from the drive's design-rule gain is refused by `check_gains`: a file
#: tuned for another motor, or a slip of units; tuning moves gains by a few times at most.
MAX_GAIN_FACTOR = 1000.0


def check_gains(drive: Drive, gains: dict, source: str) -> None:
    """Refuse a gain of ``gains`` (name -> value) more than `MAX_GAIN_FACTOR` times above or below the
    same gain of ``drive`` (its design-rule gains), with one line naming `source` (``--gains g.toml``)."""
    for name, value in gains.items():
        nominal = float(np.asarray(get_leaf(drive, name)))
        if not (nominal > 0 and math.isfinite(nominal)) or value <= 0:
            continue
        ratio = value / nominal
        if ratio > MAX_GAIN_FACTOR or ratio < 1.0 / MAX_GAIN_FACTOR:
            raise ParameterError(
                f"{source}: {name} = {value:g} is {ratio:.3g}x this drive's design-rule gain {nominal:.4g} "
                f"(more than {MAX_GAIN_FACTOR:g}x away: gains tuned for another motor, or another unit?): "
                "give gains tuned for this drive (pmsmjax tune with its --motor), or drop the gains file."
            )


def apply_gains(drive: Drive, gains) -> Drive:
    """``drive`` with gains from a dict or a gains TOML file (as written by ``pmsmjax tune``)."""
    if not isinstance(gains, dict):
        gains = read_gains_toml(gains)
    names = resolve_names(drive, list(gains))
    dtype = drive.machine.motor.R.dtype
    return set_leaves(drive, names, [jnp.asarray(gains[n], dtype) for n in names])
