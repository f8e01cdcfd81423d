"""Commands killed part-way leave no debris, and a rerun finishes with the same result.

Each kill lands at a deterministic point: while a named output file is being written (its temporary
file full, not yet renamed), the command sends itself the signal. SIGTERM (and SIGHUP) end the command
as Ctrl-C does (`pmsmjax.cli.main`): one line, exit 128 + the signal's number, the temporary file and the
folder's lock removed, finished chunks and checkpoints kept. SIGKILL cannot be handled: the dead run's lock
and temporary file stay, and the next run takes the lock over and removes them
([`pmsmjax.io.folder_lock`][pmsmjax.io.folder_lock]). Damaged files left by something else (a truncated
chunk, a wrong compilation-cache entry) are recomputed with one warning naming them.

In-process runs of tiny drives; the SIGKILL test and tune are the only subprocess or long ones (slow).
"""

import json
import os
import signal
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from pmsmjax.cli import main
from pmsmjax.io.folder_lock import LOCK_NAME, orphan_temporaries
from pmsmjax.io.logs import atomic_write

ROOT = Path(__file__).resolve().parents[2]
BOOK = ROOT / "pmsmjax" / "presets" / "motors" / "book.toml"


@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> Path:
    """The book drive with a 20 ms scenario (load step at 10 ms)."""
    path = tmp_path_factory.mktemp("drive") / "tiny.toml"
    text = BOOK.read_text().replace("duration_s = 0.4", "duration_s = 0.02")
    path.write_text(text.replace("load_time_s = 0.2", "load_time_s = 0.01"))
    return path


def mc_argv(out, tiny):
    return [
        "montecarlo", "--motor", str(tiny), "--n", "8", "--chunk-size", "4", "--sensitivity-runs", "2",
        "--devices", "1", "--no-progress", "--no-figures", "--out", str(out),
    ]  # fmt: skip


def kill_while_writing(monkeypatch, name: str, signum: int):
    """Send ``signum`` to this process while the file ``name`` is being written: its temporary file holds
    every byte, the rename has not happened. Returns the list of kills made (one at most)."""
    kills = []

    def killing(path, writer, mode="wb"):
        def write_then_die(f):
            writer(f)
            if Path(path).name == name and not kills:
                kills.append(path)
                f.flush()
                os.kill(os.getpid(), signum)

        return atomic_write(path, write_then_die, mode)

    for module in list(sys.modules.values()):
        if getattr(module, "__name__", "").startswith(("pmsmjax", "tuning")):
            if getattr(module, "atomic_write", None) is atomic_write:
                monkeypatch.setattr(module, "atomic_write", killing)
    return kills


def assert_no_debris(out: Path):
    assert not (out / LOCK_NAME).exists()
    assert orphan_temporaries(out) == []
    assert not [p for p in out.rglob("*.tmp")]


def summary_figures(summary: dict) -> dict:
    """What a rerun must reproduce: the study's figures, not its timings."""
    return {k: summary[k] for k in ("metrics", "failures", "n_runs")}


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP])
def test_montecarlo_terminated_mid_chunk_leaves_no_debris_and_resumes(
    tmp_path, tiny, capsys, monkeypatch, signum
):
    clean = tmp_path / "clean"
    assert main(mc_argv(clean, tiny)) == 0
    out = tmp_path / "killed"
    kills = kill_while_writing(monkeypatch, "chunk_00001.npz", signum)
    assert main(mc_argv(out, tiny)) == 128 + signum
    err = capsys.readouterr().err.strip().splitlines()
    assert kills and len(err) == 1
    assert err[0].startswith(f"pmsmjax montecarlo: terminated by {signal.Signals(signum).name}: ")
    assert "rerun the same command to resume" in err[0]
    assert_no_debris(out)
    assert sorted(p.name for p in (out / "chunks").iterdir()) == ["chunk_00000.npz"]  # the finished one
    monkeypatch.undo()
    assert main(mc_argv(out, tiny)) == 0
    again = json.loads((out / "summary.json").read_text())
    assert again["chunks"]["loaded"] == 1 and again["chunks"]["computed_now"] == 1
    assert summary_figures(again) == summary_figures(json.loads((clean / "summary.json").read_text()))
    assert_no_debris(out)


def test_truncated_chunk_is_recomputed_with_one_warning_naming_it(tmp_path, tiny, capsys):
    out = tmp_path / "mc"
    assert main(mc_argv(out, tiny)) == 0
    first = json.loads((out / "summary.json").read_text())
    chunk = out / "chunks" / "chunk_00001.npz"
    chunk.write_bytes(chunk.read_bytes()[:300])
    capsys.readouterr()
    assert main(mc_argv(out, tiny)) == 0
    warnings = [ln for ln in capsys.readouterr().err.splitlines() if "warning" in ln]
    assert len(warnings) == 1 and str(chunk) in warnings[0] and "damaged" in warnings[0], warnings
    zipfile.ZipFile(chunk).testzip()  # rewritten whole
    assert summary_figures(json.loads((out / "summary.json").read_text())) == summary_figures(first)


def demo_argv(out, tiny):
    return ["demo", "--motor", str(tiny), "--no-figures", "--out", str(out)]


def test_demo_terminated_while_writing_its_trace_leaves_nothing_half(tmp_path, tiny, capsys, monkeypatch):
    out = tmp_path / "demo"
    kill_while_writing(monkeypatch, "trace.csv", signal.SIGTERM)
    assert main(demo_argv(out, tiny)) == 143
    assert capsys.readouterr().err.startswith("pmsmjax demo: terminated by SIGTERM")
    assert_no_debris(out)
    assert not (out / "trace.csv").exists() and not (out / "summary.json").exists()
    monkeypatch.undo()
    assert main(demo_argv(out, tiny)) == 0
    trace = np.loadtxt(out / "trace.csv", delimiter=",", skiprows=1)
    assert trace.shape[0] == 200  # 20 ms at 10 kHz, whole
    assert_no_debris(out)


@pytest.mark.slow
def test_identify_terminated_while_writing_leaves_no_debris(tmp_path, tiny, capsys, monkeypatch):
    log_dir = tmp_path / "log"
    demo = ["demo", "--motor", str(tiny), "--duration-s", "0.2", "--load-time-s", "0.1", "--no-figures"]
    assert main([*demo, "--out", str(log_dir)]) == 0

    def argv(out):
        return [
            "identify", str(log_dir / "trace.csv"), "--pole-pairs", "4", "--out", str(out),
            "--columns", "u_d=u_d_ref", "u_q=u_q_ref",
        ]  # fmt: skip

    clean, out = tmp_path / "clean", tmp_path / "id"
    kill_while_writing(monkeypatch, "params.json", signal.SIGTERM)
    assert main(argv(out)) == 143
    assert "pmsmjax identify: terminated by SIGTERM" in capsys.readouterr().err
    assert_no_debris(out)
    assert not (out / "params.json").exists()
    monkeypatch.undo()
    status = main(argv(out))
    assert main(argv(clean)) == status  # the same verdict (this log leaves R undetermined: exit 1)
    params = lambda p: json.loads((p / "params.json").read_text())["parameters"]  # noqa: E731
    assert params(out) == params(clean)
    assert_no_debris(out)


@pytest.mark.slow
def test_tune_terminated_at_its_checkpoint_resumes_to_the_same_gains(tmp_path, capsys, monkeypatch):
    argv = ["tune", "--train", "2", "--heldout", "2", "--iterations", "4", "--no-progress"]
    argv += ["--duration-s", "0.2", "0.2", "--method", "adam", "--eval-substeps", "1"]
    clean, out = tmp_path / "clean", tmp_path / "killed"
    assert main([*argv, "--out", str(clean)]) == 0
    kill_while_writing(monkeypatch, "checkpoint.npz", signal.SIGTERM)
    assert main([*argv, "--out", str(out)]) == 143
    assert "terminated by SIGTERM" in capsys.readouterr().err
    assert_no_debris(out)
    monkeypatch.undo()
    assert main([*argv, "--out", str(out)]) == 0
    gains = lambda p: json.loads((p / "result.json").read_text())["gains"]["after"]  # noqa: E731
    assert gains(out) == pytest.approx(gains(clean), rel=1e-9)
    assert_no_debris(out)


#: A child that runs the study and is SIGKILLed by itself once chunk 1's temporary file is full.
KILLED_CHILD = """
import os, signal, sys
import pmsmjax.io.logs as logs
import tuning.montecarlo.runner as runner
from pathlib import Path
real = logs.atomic_write
def dying(path, writer, mode="wb"):
    def write(f):
        writer(f)
        if Path(path).name == "chunk_00001.npz":
            f.flush()
            os.kill(os.getpid(), signal.SIGKILL)
    return real(path, write, mode)
runner.atomic_write = dying
from pmsmjax.cli import main
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.slow
def test_sigkilled_montecarlo_debris_is_removed_by_the_next_run(tmp_path, tiny, capsys):
    out = tmp_path / "mc"
    env = {**os.environ, "PYTHONPATH": str(ROOT), "JAX_PLATFORMS": "cpu"}
    child = subprocess.run(
        [sys.executable, "-c", KILLED_CHILD, *mc_argv(out, tiny)], env=env, capture_output=True, timeout=300
    )
    assert child.returncode == -signal.SIGKILL, child.stderr
    debris = orphan_temporaries(out)
    assert (out / LOCK_NAME).exists() and [p.name[:17] for p in debris] == [".chunk_00001.npz."]
    capsys.readouterr()
    assert main(mc_argv(out, tiny)) == 0
    err = capsys.readouterr().err
    assert "took over the lock" in err and "removed the 1 unfinished temporary file" in err, err
    assert_no_debris(out)
    clean = tmp_path / "clean"
    assert main(mc_argv(clean, tiny)) == 0
    read = lambda p: summary_figures(json.loads((p / "summary.json").read_text()))  # noqa: E731
    assert read(out) == read(clean)


def test_orphans_are_ours_only(tmp_path):
    """Only the writers' ``.NAME.XXXXXXXX.tmp`` files count: a user's ``notes.tmp`` or ``.cache.tmp``
    stays, and so does a sub-folder held by another command."""
    (tmp_path / "chunks").mkdir()
    ours = [tmp_path / ".trace.csv.ab12cd_9.tmp", tmp_path / "chunks" / ".chunk_00001.npz.k2j4h5g6.tmp"]
    theirs = [tmp_path / "notes.tmp", tmp_path / ".cache.tmp", tmp_path / ".trace.csv.short.tmp"]
    held = tmp_path / "other"
    held.mkdir()
    (held / LOCK_NAME).write_text("{}")
    theirs.append(held / ".trace.csv.ab12cd_9.tmp")
    for p in ours + theirs:
        p.write_text("x")
    assert orphan_temporaries(tmp_path) == sorted(ours)


def _triple(x):
    return x * 3.0


def _pair(x):
    return x + 1.0, x.sum()


def test_wrong_compilation_cache_entry_is_evicted_and_rewritten(tmp_path):
    """An entry holding another program's code (a copied cache) is removed with one warning and written
    again; the next load takes it without a warning. (Without the check it fails every run.)"""
    import warnings

    import jax
    import jax.numpy as jnp
    from jax._src import compilation_cache as jax_cache

    from pmsmjax.cli import compilation_cache

    before = jax.config.jax_compilation_cache_dir
    cache = tmp_path / "cache"
    jax.config.update("jax_compilation_cache_dir", str(cache))
    jax_cache.reset_cache()
    compilation_cache.guard()

    def run():
        jax.clear_caches()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            jax.jit(_triple)(jnp.ones(5))
            out = jax.jit(_pair)(jnp.ones(5))
        return out, [str(w.message) for w in caught if "compilation cache entry" in str(w.message)]

    try:
        assert run()[1] == []
        (triple,) = cache.glob("jit__triple-*-cache")
        (pair,) = cache.glob("jit__pair-*-cache")
        pair.write_bytes(triple.read_bytes())
        out, said = run()
        assert float(out[1]) == 5.0
        assert len(said) == 1 and pair.name in said[0] and "holds the program jit__triple" in said[0], said
        assert pair.exists() and pair.read_bytes() != triple.read_bytes()  # written again
        assert run()[1] == []
    finally:
        jax.config.update("jax_compilation_cache_dir", before)
        jax_cache.reset_cache()
        jax.clear_caches()
