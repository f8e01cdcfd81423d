"""JAX's persistent compilation cache for every command: a program compiled by one run of ``pmsmjax``
(the drive's scan, a tuning step, a Monte Carlo chunk) is loaded from disk by the next run with the same
shapes instead of compiled again, so a repeated command answers in about the time of its imports, run and
figures.

Where: ``$PMSMJAX_CACHE_DIR`` if set (empty, ``0`` or ``off`` turns the cache off), else
``$XDG_CACHE_HOME/pmsmjax/jax``, else ``~/.cache/pmsmjax/jax``. ``--no-compile-cache`` on any command turns
it off for that run. A cache directory the user chose for JAX itself (``JAX_COMPILATION_CACHE_DIR``, or
``jax.config`` in a process that runs `pmsmjax.cli.main`) is left as it is. JAX keys each entry on
the program, the compile options and the jaxlib version, so a stale entry is never used; deleting the
folder is always safe.
"""

import os
import sys
from pathlib import Path

#: Values of ``PMSMJAX_CACHE_DIR`` that turn the cache off.
OFF = ("", "0", "off", "false", "no", "none")


def cache_dir(environ=os.environ) -> Path | None:
    """The cache folder the environment asks for, or None when it turns the cache off."""
    chosen = environ.get("PMSMJAX_CACHE_DIR")
    if chosen is not None:
        return None if chosen.strip().lower() in OFF else Path(chosen).expanduser()
    base = environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "pmsmjax" / "jax"


def enable(directory: Path | None) -> Path | None:
    """Point JAX's persistent cache at ``directory`` (every program, however quick to compile: a command's
    programs are a few, and the small ones add up) unless JAX already has one; returns the folder in use,
    or None. Works before JAX is imported (through JAX's environment variables, so a refusal of bad input
    still loads no JAX) and after."""
    if directory is None:
        return None
    if "jax" in sys.modules:
        import jax

        if jax.config.jax_compilation_cache_dir:
            return Path(jax.config.jax_compilation_cache_dir)
    elif os.environ.get("JAX_COMPILATION_CACHE_DIR"):
        return Path(os.environ["JAX_COMPILATION_CACHE_DIR"])
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        print(f"pmsmjax: warning: compilation cache off ({directory}: {err.strerror})", file=sys.stderr)
        return None
    settings = {
        "jax_compilation_cache_dir": str(directory),
        "jax_persistent_cache_min_compile_time_secs": 0.0,
        "jax_persistent_cache_min_entry_size_bytes": 0,
    }
    if "jax" in sys.modules:
        import jax

        for name, value in settings.items():
            jax.config.update(name, value)
    else:
        os.environ.update({name.upper(): str(value) for name, value in settings.items()})
    return directory
