"""Array type aliases used in signatures across pmsmjax (one module, so the convention has one home)."""

from jaxtyping import Array, ArrayLike

__all__ = ["Array", "ArrayLike"]
