"""The XLA:CPU setting pmsmjax asks for: small loops compiled as one kernel.

XLA:CPU runs a compiled program as a sequence of kernels ("thunks"). A ``while`` loop whose body has more
than a few kernels pays a dispatch per kernel per iteration (tens of ns; more when the body's buffers are
large enough for the executor to schedule it as a task graph). A drive simulation is loops of tiny
bodies (one PWM period, its RK4 sub-steps), so that dispatch, not arithmetic, sets its cost. XLA's
small-while-loop pass compiles a whole loop into one kernel instead, but by default only when the loop
touches at most 1 kB; a flux map's coefficient table (:mod:`pmsmjax.machines.flux_map`, 100 to 400 kB)
and any batched run exceed that.

:func:`request_small_loop_kernels` raises the limit to :data:`SMALL_LOOP_BYTES` through ``XLA_FLAGS``
(``--xla_backend_extra_options=xla_cpu_small_while_loop_byte_threshold=N``) when :mod:`pmsmjax` is
imported. Measured on the book drive (float32, 2 cores, ``python -m benchmarks.flux_map_cost``): one
run 1.24 -> 0.79 us per period with the linear plant and 3.6 -> 2.4 us with the flux-map plant; a batch
of 64, 0.16 -> 0.12 and 3.5 -> 1.6 us per run and period. Loops over more than the limit (large Monte
Carlo batches) keep XLA's default, multi-threaded execution.

It is a request, not a requirement: XLA reads ``XLA_FLAGS`` when it compiles, so it applies to every
computation compiled after ``import pmsmjax``, and a user who sets ``xla_backend_extra_options``
themselves keeps their own value (``...=xla_cpu_small_while_loop_byte_threshold=0`` switches the pass
off). GPUs ignore it.
"""

import os

__all__ = ["SMALL_LOOP_BYTES", "request_small_loop_kernels"]

#: Largest loop compiled as one kernel, in bytes its instructions touch (XLA counts a table once per
#: lookup: an RK4 sub-step of a float64 41 x 41 flux map reads its 410 kB table four times).
SMALL_LOOP_BYTES = 1 << 22
_OPTION = "xla_backend_extra_options"


def request_small_loop_kernels(environ=os.environ) -> bool:
    """Add the small-loop limit to ``environ["XLA_FLAGS"]`` unless it already sets
    ``xla_backend_extra_options``; returns whether it did."""
    flags = environ.get("XLA_FLAGS", "")
    if _OPTION in flags:
        return False
    limit = f"--{_OPTION}=xla_cpu_small_while_loop_byte_threshold={SMALL_LOOP_BYTES}"
    environ["XLA_FLAGS"] = f"{flags} {limit}".strip()
    return True
