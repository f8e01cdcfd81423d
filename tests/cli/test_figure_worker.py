"""The figure worker: a process forked before JAX loads draws a figure byte for byte as the command would,
hands back the exceptions it meets, and leaves no process or temporary file when it is ended mid-figure.

The worker is exercised in a fresh interpreter (a subprocess): under pytest JAX is already loaded, where
``FigureWorker.start`` refuses to fork and the command draws every figure itself.
"""

import pickle
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from pmsmjax.cli.figure_worker import FigureWorker
from pmsmjax.plotting.traces import save_overview_figure
from pmsmjax.presets import book_drive, book_scenario
from pmsmjax.simulate import simulate


def _run(code: str, cwd) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)], cwd=cwd, capture_output=True, text=True, timeout=120
    )


def test_no_worker_once_jax_is_loaded():
    assert FigureWorker.start(preload=lambda: None) is None


@pytest.mark.slow
def test_worker_draws_the_overview_byte_for_byte(tmp_path):
    scenario = book_scenario(duration_s=0.05, load_time_s=0.02)
    trace = simulate(book_drive(), scenario, decimate=5).to_numpy()
    (tmp_path / "trace.pkl").write_bytes(pickle.dumps(trace))
    (tmp_path / "here").mkdir()
    (tmp_path / "there").mkdir()
    save_overview_figure(trace, tmp_path / "here" / "overview.png", "a title", 15.0, 180.0)
    result = _run(
        """
        import pickle, sys
        from pathlib import Path
        from pmsmjax.cli.figure_worker import FigureWorker

        def preload():
            import pmsmjax.plotting.traces

        worker = FigureWorker.start(preload=preload)
        assert worker is not None and "jax" not in sys.modules
        trace = pickle.loads(Path("trace.pkl").read_bytes())  # loads JAX here, after the fork
        from pmsmjax.plotting.traces import save_overview_figure

        worker.submit(save_overview_figure, trace, Path("there/overview.png"), "a title", 15.0, 180.0)
        print(worker.result())
        worker.close()
        """,
        tmp_path,
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "there/overview.png"
    assert (tmp_path / "there" / "overview.png").read_bytes() == (
        tmp_path / "here" / "overview.png"
    ).read_bytes()


def test_worker_hands_back_its_exception_and_is_reaped(tmp_path):
    result = _run(
        """
        import os, math
        from pmsmjax.cli.figure_worker import FigureWorker

        worker = FigureWorker.start(preload=lambda: None)
        worker.submit(math.sqrt, -1.0)
        try:
            worker.result()
        except ValueError as err:
            print("raised", err)
        worker.submit(math.factorial, 5)
        print("value", worker.result())
        pid = worker.pid
        worker.close()
        try:
            os.kill(pid, 0)
            print("still there")
        except ProcessLookupError:
            print("gone")
        """,
        tmp_path,
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.split("\n")[:3] == ["raised math domain error", "value 120", "gone"]


def test_closing_mid_figure_leaves_no_temporary_file(tmp_path):
    """A command ended while the worker draws (Ctrl-C, SIGTERM) closes it: the worker's atomic write
    removes its temporary file and the worker exits."""
    result = _run(
        """
        import os, time
        from pathlib import Path
        from pmsmjax.cli.figure_worker import FigureWorker
        from pmsmjax.io.logs import atomic_write

        def slow_write(f):
            f.write(b"partial")
            time.sleep(30)

        def draw(path):
            return atomic_write(Path(path), slow_write)

        worker = FigureWorker.start(preload=lambda: None)
        worker.submit(draw, "figure.png")
        time.sleep(1.0)
        t0 = time.perf_counter()
        worker.close()
        print(f"{time.perf_counter() - t0:.1f}")
        print(sorted(os.listdir(".")))
        """,
        tmp_path,
    )
    assert result.returncode == 0, result.stderr
    seconds, listing = result.stdout.strip().split("\n")
    assert float(seconds) < 5.0
    assert listing == "[]"


def test_trace_survives_the_pipe():
    trace = simulate(book_drive(), book_scenario(duration_s=0.01, load_time_s=0.005)).to_numpy()
    again = pickle.loads(pickle.dumps(trace))
    assert np.array_equal(np.asarray(again.i_dq), np.asarray(trace.i_dq))
    assert isinstance(again.i_dq, np.ndarray)


def test_two_workers_draw_at_once_and_both_end(tmp_path):
    """A second worker forked after the first must not hold the first one's pipe: each ends when closed."""
    result = _run(
        """
        import math, os
        from pmsmjax.cli.figure_worker import FigureWorker

        workers = FigureWorker.start_several(2, preload=lambda: None)
        assert len(workers) == 2
        for k, worker in enumerate(workers):
            worker.submit(math.factorial, 4 + k)
        print([worker.result() for worker in workers])
        pids = [worker.pid for worker in workers]
        for worker in workers:
            worker.close()
        print([os.path.exists(f"/proc/{pid}") for pid in pids])
        """,
        tmp_path,
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.split("\n")[:2] == ["[24, 120]", "[False, False]"]
