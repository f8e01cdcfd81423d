"""The devices a study runs on: a CPU's cores exposed as separate JAX devices
([`split_cpu`][tuning.montecarlo.cpu_devices.split_cpu]), so work sharded over devices runs on every core, or
the hosts of a multi-host run ([`set_up_devices`][tuning.montecarlo.cpu_devices.set_up_devices]).

XLA:CPU runs one compiled program (a vmapped scan, say) mostly on a single thread; split into N host
devices, a batch sharded over them runs N programs at once. This must happen before JAX initialises its
backends, so the command line and the benchmark call [`split_cpu`][tuning.montecarlo.cpu_devices.split_cpu]
(or [`set_up_devices`][tuning.montecarlo.cpu_devices.set_up_devices]) first thing.
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


def set_up_devices(
    devices: int | None = None,
    *,
    distributed: bool = False,
    coordinator: str | None = None,
    num_processes: int | None = None,
    process_id: int | None = None,
    compilation_cache: str | None = None,
) -> None:
    """Prepare JAX for a study, before anything initialises its backends (``pmsmjax montecarlo``).

    - `distributed`: a multi-host run: `jax.distributed.initialize` with the cluster's `coordinator`
      (``HOST:PORT``), `num_processes` and this `process_id`, each taken from the environment (SLURM,
      Open MPI, Cloud TPU, ...) when None. Otherwise the CPU is split into `devices` devices
      ([`split_cpu`][tuning.montecarlo.cpu_devices.split_cpu]; default one per core).
    - `compilation_cache`: a folder that keeps every compiled function (whatever its compile time)
      instead of the persistent cache already set; None leaves the cache as it is.
    """
    if distributed:
        given = {"coordinator_address": coordinator, "num_processes": num_processes, "process_id": process_id}
        jax.distributed.initialize(**{k: v for k, v in given.items() if v is not None})
    else:
        split_cpu(devices)
    if compilation_cache:
        jax.config.update("jax_compilation_cache_dir", compilation_cache)
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
