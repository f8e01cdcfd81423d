"""The output-folder lock (:mod:`pmsmjax.io.folder_lock`, taken by :func:`pmsmjax.cli.main`): a second
command on a folder in use is refused with one line naming the first and writes nothing; a lock left by a
dead process is taken over; the lock goes however a command ends.

The commands' own work is replaced by a stand-in ``run`` (what it sees of the lock is the point, not the
work) except in the last test, where two real ``montecarlo`` processes race for one folder.
"""

import json
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

import pmsmjax.cli
import pmsmjax.cli.identify
from pmsmjax.io.folder_lock import LOCK_NAME, acquire, read_lock
from pmsmjax.spec.validation import ParameterError

ROOT = Path(__file__).resolve().parents[2]
ENV = {**os.environ, "PYTHONPATH": str(ROOT), "JAX_PLATFORMS": "cpu"}


def _dead_pid() -> int:
    """The pid of a process that has ended (and been reaped)."""
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def _identify_argv(out, log="log.csv") -> list[str]:
    return ["identify", str(log), "--pole-pairs", "4", "--out", str(out)]


@pytest.fixture
def stand_in(monkeypatch):
    """Replace identify's work by ``behaviour(args)``; records the lock file's content seen during the run."""
    seen = []

    def install(behaviour):
        def run(args):
            seen.append(read_lock(Path(args.out) / LOCK_NAME))
            return behaviour(args)

        monkeypatch.setattr(pmsmjax.cli.identify, "run", run)
        return seen

    return install


def test_held_lock_refuses_second_command_naming_it(tmp_path, capsys, stand_in):
    out = tmp_path / "out"
    out.mkdir()
    holder_argv = ["pmsmjax", "montecarlo", "--out", str(out), "--seed", "1"]
    code = (
        "import sys, time; from pmsmjax.io.folder_lock import acquire; "
        f"acquire({str(out)!r}, {holder_argv!r}); print('held', flush=True); time.sleep(60)"
    )
    holder = subprocess.Popen([sys.executable, "-c", code], env=ENV, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        ran = stand_in(lambda args: 0)
        assert pmsmjax.cli.main(_identify_argv(out)) == 2
        err = capsys.readouterr().err
        assert ran == []  # refused before the command's own checks
        assert err.count("\n") == 1 and err.startswith("pmsmjax identify: error: output folder")
        lock = read_lock(out / LOCK_NAME)
        for part in (" ".join(holder_argv), f"pid {holder.pid}", socket.gethostname(), lock["time"]):
            assert part in err
        assert sorted(p.name for p in out.iterdir()) == [LOCK_NAME]  # nothing written, the lock kept
        assert lock["pid"] == holder.pid
    finally:
        holder.kill()
        holder.wait()


def test_lock_of_another_host_is_refused_with_the_file_to_delete(tmp_path):
    (tmp_path / LOCK_NAME).write_text(json.dumps({"pid": 1, "host": "elsewhere", "argv": ["x"], "time": "t"}))
    with pytest.raises(ParameterError, match=f"if it no longer runs on elsewhere, delete {tmp_path}"):
        acquire(tmp_path, ["pmsmjax", "demo"])


def test_stale_lock_is_taken_over_with_a_warning(tmp_path, capsys, stand_in):
    dead = _dead_pid()
    stale = {"pid": dead, "host": socket.gethostname(), "argv": ["pmsmjax", "tune"], "time": "earlier"}
    (tmp_path / LOCK_NAME).write_text(json.dumps(stale))
    ran = stand_in(lambda args: 0)
    assert pmsmjax.cli.main(_identify_argv(tmp_path)) == 0
    assert ran[0]["pid"] == os.getpid() and ran[0]["argv"] == ["pmsmjax", *_identify_argv(tmp_path)]
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "warning: output folder" in err and f"pid {dead}" in err
    assert not (tmp_path / LOCK_NAME).exists()


def test_two_takers_of_one_stale_lock_one_wins(tmp_path):
    """Once a command has taken a stale lock over, a second that saw the same stale lock is refused."""
    stale = {"pid": _dead_pid(), "host": socket.gethostname(), "argv": [], "time": "earlier"}
    (tmp_path / LOCK_NAME).write_text(json.dumps(stale))
    with pytest.warns(UserWarning, match="took over"):
        first = acquire(tmp_path, ["first"])
    with pytest.raises(ParameterError, match="'first'"):
        acquire(tmp_path, ["second"])
    first.release()
    assert not (tmp_path / LOCK_NAME).exists()


def test_lock_held_during_a_normal_run_and_gone_after(tmp_path, stand_in):
    out = tmp_path / "new" / "out"

    def write(args):
        (Path(args.out) / "params.json").write_text("{}")
        return 0

    ran = stand_in(write)
    assert pmsmjax.cli.main(_identify_argv(out)) == 0
    assert ran[0]["pid"] == os.getpid() and ran[0]["host"] == socket.gethostname()
    assert sorted(p.name for p in out.iterdir()) == ["params.json"]


@pytest.mark.parametrize(
    "failure, status",
    [(ParameterError("log.csv: no time column"), 2), (KeyboardInterrupt(), 130), (RuntimeError("bug"), 1)],
)
def test_failed_run_leaves_no_lock_and_no_folder(tmp_path, stand_in, capsys, failure, status):
    out = tmp_path / "a" / "b"

    def fail(args):
        raise failure

    ran = stand_in(fail)
    assert pmsmjax.cli.main(_identify_argv(out)) == status
    assert ran[0]["pid"] == os.getpid()  # it ran under the lock
    assert list(tmp_path.iterdir()) == []  # the folders made for the lock are gone again
    assert capsys.readouterr().err.count("\n") == 1


def test_failed_run_keeps_an_existing_folder_and_what_it_wrote(tmp_path, stand_in):
    def write_then_fail(args):
        (Path(args.out) / "chunk_0.npz").write_bytes(b"")
        raise KeyboardInterrupt("the finished chunks are kept")

    stand_in(write_then_fail)
    assert pmsmjax.cli.main(_identify_argv(tmp_path / "out")) == 130
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["chunk_0.npz"]
    stand_in(lambda args: 1)
    assert pmsmjax.cli.main(_identify_argv(tmp_path)) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_out_that_is_a_file_is_refused_before_locking(tmp_path, capsys, stand_in):
    (tmp_path / "f").write_text("x")
    ran = stand_in(lambda args: 0)
    assert pmsmjax.cli.main(_identify_argv(tmp_path / "f")) == 2
    assert ran == [] and "is an existing file" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f"]


def test_two_concurrent_montecarlo_runs_on_one_folder(tmp_path):
    """Two real processes: exactly one proceeds (and releases the folder when done), the other is refused
    (exit 2, one line naming the first)."""
    out = tmp_path / "same"
    argv = [sys.executable, "-m", "pmsmjax", "montecarlo", "--out", str(out), "--n", "2"]
    argv += ["--sensitivity-runs", "0", "--no-progress", "--no-figures"]
    procs = [
        subprocess.Popen(
            argv + ["--seed", str(seed)], env=ENV, stderr=subprocess.PIPE, text=True, cwd=tmp_path
        )
        for seed in (1, 2)
    ]
    try:
        deadline = time.monotonic() + 60
        while all(p.poll() is None for p in procs) and time.monotonic() < deadline:
            time.sleep(0.05)
        refused = [p for p in procs if p.poll() is not None]
        assert len(refused) == 1, "neither command ended"
        (loser,) = refused
        (winner,) = [p for p in procs if p is not loser]
        err = loser.stderr.read()
        assert loser.returncode == 2 and err.count("\n") == 1, err
        winner_seed = 1 if winner is procs[0] else 2
        assert f"pid {winner.pid}" in err and f"--seed {winner_seed}" in err
        assert read_lock(out / LOCK_NAME)["pid"] == winner.pid
        winner.wait(timeout=120)
        assert winner.returncode == 0, winner.stderr.read()
        assert (out / "summary.json").is_file()
        assert not (out / LOCK_NAME).exists()
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
                p.wait()
