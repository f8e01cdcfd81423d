"""A second process that draws figures while the command is still simulating.

Drawing and writing a command's PNG files is pure Python and single-threaded (matplotlib's Agg); on a drive
whose run is compiled and cached it takes about as long as everything else the command does. A
[`FigureWorker`][pmsmjax.cli.figure_worker.FigureWorker] is forked at the start of a command, before
JAX is loaded (a fork of a process running JAX's threads is unsafe): it loads matplotlib while the command
loads JAX and simulates, then draws the figures it is handed on the machine's second core while the command
draws the others. Each figure is the same file, byte for byte, as the command would draw itself.

Where a worker cannot help or cannot be forked safely (one core, JAX already loaded as under pytest or in a
notebook, an operating system other than Linux),
[`FigureWorker.start`][pmsmjax.cli.figure_worker.FigureWorker.start] returns ``None`` and the command draws
every figure itself.

The worker never runs the command's clean-up: it leaves through ``os._exit`` whatever happens, so the
command's folder lock and temporary files stay the command's. A task that fails in the worker comes back as
the exception it raised, re-raised in the command.
"""

import os
import pickle
import signal
import struct
import sys
from collections.abc import Callable

_LENGTH = struct.Struct("!Q")

#: The command's ends of its workers' pipes, which a worker forked later closes.
_PARENT_ENDS: set[int] = set()


def _write_message(fd: int, payload) -> None:
    data = pickle.dumps(payload, protocol=pickle.HIGHEST_PROTOCOL)
    view = memoryview(_LENGTH.pack(len(data)) + data)
    while view:
        view = view[os.write(fd, view) :]


def _read_message(fd: int):
    """The next message from ``fd``; ``EOFError`` when the other end closed."""

    def read_exactly(n: int) -> bytes:
        chunks, left = [], n
        while left:
            chunk = os.read(fd, min(left, 1 << 20))
            if not chunk:
                raise EOFError
            chunks.append(chunk)
            left -= len(chunk)
        return b"".join(chunks)

    (n,) = _LENGTH.unpack(read_exactly(_LENGTH.size))
    return pickle.loads(read_exactly(n))


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


class FigureWorker:
    """A forked process that runs figure-drawing calls handed to it (module docstring).

    Use [`start`][pmsmjax.cli.figure_worker.FigureWorker.start], then
    [`submit`][pmsmjax.cli.figure_worker.FigureWorker.submit] one call and collect it with
    [`result`][pmsmjax.cli.figure_worker.FigureWorker.result];
    [`close`][pmsmjax.cli.figure_worker.FigureWorker.close] ends the worker (also when the command fails
    before handing it anything).
    """

    def __init__(self, pid: int, task_fd: int, result_fd: int):
        self.pid, self._task_fd, self._result_fd = pid, task_fd, result_fd
        self._pending = False

    @classmethod
    def start(cls, preload: Callable[[], None]) -> "FigureWorker | None":
        """Fork the worker; it calls ``preload`` (import what drawing needs) and waits for a task.

        Returns ``None`` (draw in the command instead) on one core, once JAX is loaded, or off Linux."""
        # Linux only: macOS's system frameworks are not safe to use in a forked child (Python's own
        # multiprocessing stopped forking there), and Windows has no fork.
        if not sys.platform.startswith("linux") or "jax" in sys.modules or _cores() < 2:
            return None
        task_read, task_write = os.pipe()
        result_read, result_write = os.pipe()
        pid = os.fork()
        if pid == 0:  # the worker
            os.close(task_write)
            os.close(result_read)
            for fd in _PARENT_ENDS:  # an earlier worker's pipe ends: its end of file is its parent's alone
                os.close(fd)
            code = 1
            try:
                # SIGTERM ends a figure as Ctrl-C does: the atomic write removes its temporary file.
                signal.signal(signal.SIGTERM, _interrupt)
                preload()
                code = _serve(task_read, result_write)
            finally:
                os._exit(code)  # never the command's clean-up (its lock, its temporary files)
        os.close(task_read)
        os.close(result_write)
        _PARENT_ENDS.update((task_write, result_read))
        return cls(pid, task_write, result_read)

    @classmethod
    def start_several(cls, count: int, preload: Callable[[], None]) -> "list[FigureWorker]":
        """Up to ``count`` workers ([`start`][pmsmjax.cli.figure_worker.FigureWorker.start]); none where a
        worker cannot be forked."""
        workers = []
        for _ in range(count):
            worker = cls.start(preload)
            if worker is None:
                break
            workers.append(worker)
        return workers

    def submit(self, function: Callable, *args, **kwargs) -> None:
        """Hand ``function(*args, **kwargs)`` to the worker (``function`` importable by name, the arguments
        picklable)."""
        _write_message(self._task_fd, (function, args, kwargs))
        self._pending = True

    def result(self):
        """Wait for the submitted call and return its value, or raise the exception it raised."""
        self._pending = False
        try:
            ok, value = _read_message(self._result_fd)
        except EOFError:
            raise RuntimeError("the figure worker ended without drawing its figure") from None
        if not ok:
            raise value
        return value

    def close(self) -> None:
        """End the worker (it exits on the closed pipe) and reap it."""
        if self.pid is None:
            return
        for fd in (self._task_fd, self._result_fd):
            _PARENT_ENDS.discard(fd)
            try:
                os.close(fd)
            except OSError:
                pass
        try:
            if self._pending:
                # Interrupted mid-figure: SIGTERM ends its drawing as it ends a command (the file being
                # written is removed by the atomic write's clean-up), without waiting for the figure.
                os.kill(self.pid, signal.SIGTERM)
            os.waitpid(self.pid, 0)
        except (ChildProcessError, ProcessLookupError):
            pass
        self.pid = None


def _interrupt(signum, frame):
    raise KeyboardInterrupt(f"signal {signum}")


def _serve(task_fd: int, result_fd: int) -> int:
    """The worker's loop: run each task, send back ``(True, value)`` or ``(False, exception)``; exit 0 when
    the command closes the pipe."""
    while True:
        try:
            function, args, kwargs = _read_message(task_fd)
        except EOFError:
            return 0
        try:
            reply = (True, function(*args, **kwargs))
        except Exception as err:  # handed back to the command, which raises it
            reply = (False, err)
        try:
            _write_message(result_fd, reply)
        except (BrokenPipeError, pickle.PicklingError):
            return 1
