"""The XLA:CPU setting pmsmjax asks for: small loops compiled as one kernel.

XLA:CPU runs a compiled program as a sequence of kernels ("thunks"). A ``while`` loop whose body has more
than a few kernels pays a dispatch per kernel per iteration (tens of ns; more when the body's buffers are
large enough for the executor to schedule it as a task graph). A drive simulation is loops of tiny
bodies (one PWM period, its RK4 sub-steps), so that dispatch, not arithmetic, sets its cost. XLA's
small-while-loop pass compiles a whole loop into one kernel instead, but by default only when the loop
touches at most 1 kB; a flux map's coefficient table
([`pmsmjax.machines.flux_map`][pmsmjax.machines.flux_map], 100 to 400 kB) and any batched run exceed that.

[`request_small_loop_kernels`][pmsmjax.xla_cpu.request_small_loop_kernels] raises the limit to
[`SMALL_LOOP_BYTES`][pmsmjax.xla_cpu.SMALL_LOOP_BYTES] through ``XLA_FLAGS``
(``--xla_backend_extra_options=xla_cpu_small_while_loop_byte_threshold=N``) when [`pmsmjax`][pmsmjax] is
imported (its effect on the linear and flux-map drives: docs/performance.md,
``python -m benchmarks.flux_map_cost``). Loops over more than the limit (large Monte Carlo batches) keep XLA's
default, multi-threaded execution.

It is a request, not a requirement: XLA reads ``XLA_FLAGS`` when it compiles, so it applies to every
computation compiled after ``import pmsmjax``. A user's own ``xla_backend_extra_options`` (XLA's
comma-separated ``key=value`` list) get the limit added to them, unless they set it themselves
(``...=xla_cpu_small_while_loop_byte_threshold=0`` switches the pass off). GPUs ignore it.
"""

import os
import re

__all__ = ["SMALL_LOOP_BYTES", "request_small_loop_kernels"]

#: Largest loop compiled as one kernel, in bytes its instructions touch (XLA counts a table once per
#: lookup: an RK4 sub-step of a float64 41 x 41 flux map reads its 410 kB table four times).
SMALL_LOOP_BYTES = 1 << 22
_OPTION = "xla_backend_extra_options"
_LIMIT_KEY = "xla_cpu_small_while_loop_byte_threshold"


def request_small_loop_kernels(environ=os.environ) -> bool:
    """Add the small-loop limit to ``environ["XLA_FLAGS"]``: as a new ``--xla_backend_extra_options``, or
    appended to the last one the flags already give, unless that one sets the limit itself (or is quoted,
    which this does not parse); returns whether it added it."""
    flags = environ.get("XLA_FLAGS", "")
    limit = f"{_LIMIT_KEY}={SMALL_LOOP_BYTES}"
    given = list(re.finditer(rf"--{_OPTION}=(\S*)", flags))
    if not given:
        environ["XLA_FLAGS"] = f"{flags} --{_OPTION}={limit}".strip()
        return True
    last = given[-1]
    value = last.group(1)
    keys = [item.split("=", 1)[0] for item in value.split(",")]
    if _LIMIT_KEY in keys or value.startswith(("'", '"')):
        return False
    merged = f"{value},{limit}" if value else limit
    environ["XLA_FLAGS"] = f"{flags[: last.start(1)]}{merged}{flags[last.end(1) :]}"
    return True
