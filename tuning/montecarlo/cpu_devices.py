"""Expose a CPU's cores as separate JAX devices, so work sharded over devices runs on every core.

XLA:CPU runs one compiled program (a vmapped scan, say) mostly on a single thread; split into N host
devices, a batch sharded over them runs N programs at once. This must happen before JAX initialises its
backends, so the command line and the benchmark call [`split_cpu`][tuning.montecarlo.cpu_devices.split_cpu]
first thing.
"""

import os

import jax

FLAG = "xla_force_host_platform_device_count"


def split_cpu(n: int | None = None) -> int | None:
    """Make the CPU backend ``n`` devices (default: the core count) unless ``XLA_FLAGS`` already sets a
    count or JAX's backends are already initialised. Returns the count set, or None when left alone.

    Only the CPU backend is affected: with a GPU, ``jax.devices()`` still lists the GPUs.
    """
    if FLAG in os.environ.get("XLA_FLAGS", ""):
        return None
    if n is None:
        n = os.cpu_count() or 1
    try:
        jax.config.update("jax_num_cpu_devices", n)
    except RuntimeError:  # backends already initialised: too late, keep what there is
        return None
    return n
