"""The commands' persistent compilation cache (pmsmjax/cli/compilation_cache.py): where it goes, how it is
turned off, and that a program loaded from it gives the same run as one compiled afresh."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pmsmjax.cli.compilation_cache import cache_dir


def test_folder_follows_the_environment(tmp_path):
    home = Path.home()
    assert cache_dir({}) == home / ".cache" / "pmsmjax" / "jax"
    assert cache_dir({"XDG_CACHE_HOME": str(tmp_path)}) == tmp_path / "pmsmjax" / "jax"
    chosen = {"PMSMJAX_CACHE_DIR": str(tmp_path / "mine"), "XDG_CACHE_HOME": "/elsewhere"}
    assert cache_dir(chosen) == tmp_path / "mine"
    assert cache_dir({"PMSMJAX_CACHE_DIR": "~/c"}) == home / "c"
    for off in ("", "0", "off", "OFF", "none", "false"):
        assert cache_dir({"PMSMJAX_CACHE_DIR": off}) is None


def _demo(out: Path, cache: Path, *flags) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if not k.startswith("JAX_")}
    env["PMSMJAX_CACHE_DIR"] = str(cache)
    cmd = [sys.executable, "-m", "pmsmjax", "demo", "--duration-s", "0.05", "--load-time-s", "0.03"]
    return subprocess.run(
        [*cmd, "--no-figures", "--out", str(out), *flags], env=env, capture_output=True, text=True
    )


@pytest.mark.slow
def test_a_cached_program_gives_the_run_of_a_fresh_compile(tmp_path):
    cache = tmp_path / "cache"
    fresh = _demo(tmp_path / "fresh", cache)
    assert fresh.returncode == 0, fresh.stderr
    entries = sorted(p.name for p in cache.iterdir())
    assert entries, "the first run left nothing in the cache folder"
    again = _demo(tmp_path / "again", cache)
    assert again.returncode == 0, again.stderr
    assert sorted(p.name for p in cache.iterdir()) == entries, "the second run compiled new programs"
    a = np.genfromtxt(tmp_path / "fresh" / "trace.csv", delimiter=",", names=True)
    b = np.genfromtxt(tmp_path / "again" / "trace.csv", delimiter=",", names=True)
    for name in a.dtype.names:
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)


def test_no_compile_cache_writes_no_cache(tmp_path):
    cache = tmp_path / "cache"
    done = _demo(tmp_path / "out", cache, "--no-compile-cache")
    assert done.returncode == 0, done.stderr
    assert not cache.exists()
    assert (tmp_path / "out" / "trace.csv").is_file()
