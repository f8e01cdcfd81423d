"""Array type aliases used in signatures across pmsmjax (jaxtyping, shapes in the alias names)."""

import numpy as np
from jaxtyping import Array, ArrayLike, Float

Scalar = Float[Array, ""]
ScalarLike = float | Float[ArrayLike, ""]
Vec2 = Float[Array, "2"]
Vec3 = Float[Array, "3"]
RealArray = Float[Array | np.ndarray, "..."]

__all__ = ["Array", "ArrayLike", "Float", "RealArray", "Scalar", "ScalarLike", "Vec2", "Vec3"]
