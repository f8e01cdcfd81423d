"""Parameter distributions of a Monte Carlo study, and seeded (optionally Latin hypercube) sampling.

Every distribution is given as a relative tolerance around a nominal value, as data sheets state them
(``R +-20 %``), and is sampled by its inverse CDF from uniforms in (0, 1), so plain random sampling and
Latin hypercube sampling share one code path:

- ``uniform``: ``nominal (1 + tolerance (2u - 1))``, the whole band ``+-tolerance``.
- ``normal``: ``nominal (1 + tolerance / sigmas z)``, ``z = Phi^-1(u)``: the band ``+-tolerance`` is
  ``sigmas`` standard deviations (3 by default: 99.7 % of the samples inside it).
- ``lognormal``: ``nominal exp(log(1 + tolerance) / sigmas z)``: median ``nominal``, always positive,
  ``nominal (1 + tolerance)`` at ``sigmas`` standard deviations.

A parameter whose nominal value may be zero (a current sensor's offset) spreads by an *absolute* half-width
in its own unit instead (``absolute=True``): ``nominal + tolerance (2u - 1)`` (uniform) or
``nominal + tolerance / sigmas z`` (normal); lognormal is for positive parameters only.

A tolerance of 0 fixes the parameter. Samples are float64 NumPy arrays drawn on the host from
``numpy.random.default_rng(seed)``, so they do not depend on the device count or the chunking.
"""

import dataclasses
import math

import numpy as np
from scipy.special import ndtri

from pmsmjax.spec.validation import ParameterError, plain

KINDS = ("uniform", "normal", "lognormal")
SAMPLING = ("random", "latin_hypercube")


@dataclasses.dataclass(frozen=True)
class Distribution:
    """One parameter's spread.

    - `kind`: ``uniform``, ``normal`` or ``lognormal`` (see the module docstring).
    - `nominal`: the nominal value, in the parameter's SI unit.
    - `tolerance`: relative half-width of the tolerance band (0.2 for +-20 %), >= 0.
    - `sigmas`: standard deviations the band spans (normal and lognormal), > 0.
    - `absolute`: `tolerance` is a half-width in the parameter's unit, not relative (a signed parameter
      whose nominal value may be 0: a current sensor's offset, A).
    """

    kind: str
    nominal: float
    tolerance: float
    sigmas: float = 3.0
    absolute: bool = False

    def check(self, name: str) -> None:
        """Raise [`ParameterError`][pmsmjax.spec.validation.ParameterError] naming ``name`` for a malformed
        distribution."""
        if self.kind not in KINDS:
            raise ParameterError(
                f"{name}: distribution {self.kind!r} is unknown; use one of {', '.join(KINDS)}."
            )
        for field in ("nominal", "tolerance", "sigmas"):
            v = getattr(self, field)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                shown = plain(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else repr(v)
                raise ParameterError(f"{name}: {field} must be a finite number, got {shown}.")
        if self.tolerance < 0:
            raise ParameterError(
                f"{name}: tolerance must be >= 0 (a relative half-width, 0.2 for +-20 %), "
                f"got {self.tolerance}."
            )
        if self.sigmas <= 0:
            raise ParameterError(f"{name}: sigmas must be > 0, got {self.sigmas}.")
        if self.absolute and self.kind == "lognormal":
            raise ParameterError(
                f"{name}: a lognormal spread is for positive parameters; this one is signed (its tolerance "
                "is an absolute half-width): use uniform or normal."
            )

    def from_uniform(self, u: np.ndarray) -> np.ndarray:
        """Samples from uniforms ``u`` in (0, 1) by the inverse CDF (same shape as ``u``)."""
        if self.absolute:
            if self.kind == "uniform":
                return self.nominal + self.tolerance * (2.0 * u - 1.0)
            return self.nominal + self.tolerance / self.sigmas * ndtri(u)
        if self.kind == "uniform":
            return self.nominal * (1.0 + self.tolerance * (2.0 * u - 1.0))
        z = ndtri(u)
        if self.kind == "normal":
            return self.nominal * (1.0 + self.tolerance / self.sigmas * z)
        return self.nominal * np.exp(math.log1p(self.tolerance) / self.sigmas * z)

    def describe(self) -> dict:
        """The distribution as a plain ``{field: value}`` dict (for the study's report files)."""
        return dataclasses.asdict(self)


def unit_samples(n: int, n_params: int, seed: int, sampling: str = "random") -> np.ndarray:
    """``(n, n_params)`` uniforms in (0, 1): independent, or a Latin hypercube (one sample per stratum
    ``[k/n, (k+1)/n)`` of every parameter, strata paired at random)."""
    if sampling not in SAMPLING:
        raise ParameterError(f"sampling must be one of {', '.join(SAMPLING)}, got {sampling!r}.")
    rng = np.random.default_rng(seed)
    u = rng.random((n, n_params))
    if sampling == "latin_hypercube":
        strata = np.stack([rng.permutation(n) for _ in range(n_params)], axis=1)
        u = (strata + u) / n
    # Keep u away from 0 and 1 exactly, where the normal inverse CDF is infinite.
    tiny = np.finfo(np.float64).tiny
    return np.clip(u, tiny, 1.0 - np.finfo(np.float64).epsneg)


def sample(
    distributions: dict[str, Distribution], n: int, seed: int, sampling: str = "random"
) -> dict[str, np.ndarray]:
    """``{name: (n,) float64 samples}`` for every distribution, from one seeded stream."""
    for name, d in distributions.items():
        d.check(name)
    if not isinstance(n, int) or isinstance(n, bool) or n < 1:
        raise ParameterError(f"the number of runs must be an int >= 1, got {n!r}.")
    u = unit_samples(n, len(distributions), seed, sampling)
    return {name: d.from_uniform(u[:, j]) for j, (name, d) in enumerate(distributions.items())}
