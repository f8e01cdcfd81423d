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

A damaged entry (truncated, or holding another program's code: a copied or half-synchronised cache
folder) is not left to fail every run: `guard` checks each entry JAX loads (it must read, and hold the
program of its name), and an entry that fails is removed with one warning naming it, compiled afresh and
written again, so the next run loads the good one.
"""

import contextlib
import importlib.abc
import importlib.util
import os
import sys
import warnings
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
    guard()
    return directory


#: JAX's module whose cache reader `guard` wraps, and the reader's name there.
_COMPILER, _READER = "jax._src.compiler", "_cache_read"
_READ_ERROR = "Error reading persistent compilation cache entry"


def guard() -> None:
    """Check every entry JAX's persistent cache loads from now on (module docstring); idempotent. Before
    JAX is imported it waits for the import (no JAX is loaded here)."""
    module = sys.modules.get(_COMPILER)
    if module is not None:
        _wrap(module)
    elif not any(isinstance(f, _WrapOnImport) for f in sys.meta_path):
        sys.meta_path.insert(0, _WrapOnImport())


class _WrapOnImport(importlib.abc.MetaPathFinder):
    """Wraps JAX's cache reader as soon as its module has been executed."""

    def find_spec(self, name, path, target=None):
        if name != _COMPILER:
            return None
        sys.meta_path.remove(self)
        spec = importlib.util.find_spec(name)
        if spec is None or spec.loader is None:
            return spec
        run = spec.loader.exec_module

        def exec_module(module):
            run(module)
            _wrap(module)

        spec.loader.exec_module = exec_module
        return spec


def _wrap(compiler) -> None:
    read = getattr(compiler, _READER, None)
    if read is None or getattr(read, "_pmsmjax_guard", False):
        return

    def checked_read(module_name, cache_key, *args, **kwargs):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                executable, compile_time = read(module_name, cache_key, *args, **kwargs)
                problem = None
            except Exception as err:  # noqa: BLE001 (what JAX raises for an entry it cannot verify)
                executable, compile_time = None, None
                problem = f"{type(err).__name__}: {err}"
        for w in caught:
            if _READ_ERROR in str(w.message):
                problem = str(w.message).split(": ", 1)[-1]
            else:
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        if executable is not None:
            held = _module_names(executable)
            if held and module_name not in held:
                problem = f"it holds the program {held[0]}, not {module_name}"
                executable, compile_time = None, None
        if problem is not None:
            removed = _evict(cache_key)
            why = " ".join(problem.split())[:100]
            warnings.warn(
                f"compilation cache entry {removed or cache_key} could not be used ({why}): removed it; the "
                "program is compiled afresh and cached again",
                stacklevel=2,
            )
        return executable, compile_time

    checked_read._pmsmjax_guard = True
    setattr(compiler, _READER, checked_read)


def _module_names(executable) -> list[str]:
    """The names of the programs a loaded executable holds (empty when it cannot say)."""
    try:
        return [m.name for m in executable.hlo_modules()]
    except Exception:  # noqa: BLE001 (a backend without HLO modules: no check)
        return []


def _evict(cache_key: str) -> Path | None:
    """Remove the cache entry `cache_key` (its ``-cache`` and ``-atime`` files) from JAX's local cache
    folder; the entry's path, or None when the cache is not a local folder."""
    import jax

    folder = jax.config.jax_compilation_cache_dir
    if not folder or "://" in str(folder):
        return None
    entry = Path(folder) / f"{cache_key}-cache"
    for path in (entry, Path(folder) / f"{cache_key}-atime"):
        with contextlib.suppress(OSError):
            path.unlink()
    return entry
