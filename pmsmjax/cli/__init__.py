"""The ``pmsmjax`` command: ``demo`` (alias ``simulate``), ``replay``, ``tune``, ``bench``, ``pwm-compare``,
``compare``, ``identify``, ``montecarlo``, ``observe`` and ``export``.

Every subcommand checks its input before compiling anything and writes each output file atomically
(temporary file in the same folder, then rename), so an interrupted or failed run leaves no half file.

One command at a time per output folder: for a command with an output folder (``--out``), `main`
takes the folder's lock ``--out/.pmsmjax.lock`` ([`pmsmjax.io.folder_lock`][pmsmjax.io.folder_lock]) right
after parsing the flags, before the command checks or writes anything, and removes it when the command ends,
however it ends. A second command on the same folder is refused (exit 2) with the first one's command line,
pid, host and start time; a lock left by a command that died is taken over with a warning. A command refused
for its input leaves nothing: the folder made for the lock goes again when it is empty.

Each subcommand is one module of this package with ``add_parser(subparsers)``, which adds its parser and
sets ``func`` to its ``run(args) -> int`` (the exit status); a module imports what its ``run`` needs
inside ``run``, so ``pmsmjax --help`` and refusals of bad flags stay quick (no JAX at start-up; the
package ``pmsmjax`` loads its names lazily). A new subcommand is a new module and its name in
`SUBCOMMANDS`; `pmsmjax.cli.checks` has the shared flag checks.

What the user sees when something goes wrong, from `main`, always one line on stderr:

- bad input (a flag, a file, a column), or an output folder in use by another command:
  ``pmsmjax CMD: error: <what, where, the fix>``, exit 2;
- Ctrl-C: ``pmsmjax CMD: interrupted ...`` (what was kept, how to resume), exit 130; SIGTERM (what
  ``timeout``, ``kill``, systemd and batch schedulers send) and SIGHUP (the terminal closed) take the same
  path (`Terminated`, a ``KeyboardInterrupt``: every file in progress is removed, finished chunks and
  checkpoints are kept, the folder's lock goes): ``pmsmjax CMD: terminated by SIGTERM ...``, exit
  128 + the signal's number (143, 129), the shell's convention for a death by that signal;
- a failure of the program itself: ``pmsmjax CMD: internal error: ...``, exit 1 (the traceback only
  with the environment variable ``PMSMJAX_TRACEBACK=1``);
- warnings: ``pmsmjax CMD: warning: ...``.
"""

import contextlib
import importlib
import os
import signal
import sys
import threading
import warnings

from pmsmjax.cli import compilation_cache
from pmsmjax.cli.checks import Parser
from pmsmjax.spec.validation import ParameterError

#: The subcommands' modules, in the order ``pmsmjax --help`` lists them.
SUBCOMMANDS = (
    "demo",
    "replay",
    "bench",
    "tune",
    "pwm_compare",
    "compare",
    "identify",
    "montecarlo",
    "observe",
    "export",
)


def build_parser() -> Parser:
    """The ``pmsmjax`` argument parser: one subparser per module of `SUBCOMMANDS`, each with
    ``--no-compile-cache``."""
    parser = Parser(prog="pmsmjax", description="Differentiable, batched PMSM drive simulation in JAX.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for name in SUBCOMMANDS:
        importlib.import_module(f"{__name__}.{name}").add_parser(sub)
    for command in {id(p): p for p in sub.choices.values()}.values():  # an alias shares its parser
        command.add_argument(
            "--no-compile-cache",
            action="store_true",
            help="compile every program afresh instead of loading it from the persistent cache "
            "(default cache: $PMSMJAX_CACHE_DIR, else $XDG_CACHE_HOME/pmsmjax/jax or ~/.cache/pmsmjax/jax)",
        )
    return parser


def _one_line(text) -> str:
    return " ".join(str(text).split())


#: The signals handled like Ctrl-C (`main`), where the platform has them.
TERMINATING_SIGNALS = tuple(getattr(signal, n) for n in ("SIGTERM", "SIGHUP") if hasattr(signal, n))


class Terminated(KeyboardInterrupt):
    """A terminating signal (`TERMINATING_SIGNALS`) received while a command runs, raised where the
    command is, so that the clean-up of Ctrl-C runs. `signum`: the signal's number."""

    def __init__(self, signum: int):
        super().__init__()
        self.signum = signum


@contextlib.contextmanager
def _signals_as_interrupts():
    """While the block runs (in the main thread), SIGTERM and SIGHUP raise `Terminated`; yields a list that
    holds the first signal's number once one came. A second signal during the clean-up is ignored (SIGKILL
    remains for a command that must go at once); the previous handlers come back after the block."""
    received: list[int] = []
    if threading.current_thread() is not threading.main_thread():
        yield received
        return

    def handler(signum, frame):
        if received:
            return
        received.append(signum)
        raise Terminated(signum)

    previous = {}
    try:
        for s in TERMINATING_SIGNALS:
            previous[s] = signal.signal(s, handler)
        yield received
    finally:
        for s, h in previous.items():
            signal.signal(s, h)


def main(argv=None) -> int:
    """Run the command line ``argv`` (default ``sys.argv[1:]``); returns the exit status. As with any
    argparse program, ``--help`` and a flag refused while parsing (a bad number, an unknown choice) end in
    ``SystemExit`` (0 and 2; the refusal's one line is printed first)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    args = build_parser().parse_args(argv)
    prog = f"pmsmjax {args.command}"
    compilation_cache.enable(None if args.no_compile_cache else compilation_cache.cache_dir())

    def show_warning(message, category, filename, lineno, file=None, line=None):
        print(f"{prog}: warning: {_one_line(message)}", file=sys.stderr)

    with warnings.catch_warnings(), _signals_as_interrupts() as received:
        warnings.showwarning = show_warning
        try:
            with _output_folder_held(args, ["pmsmjax", *argv]) as lock:
                status = args.func(args)
                if lock is not None:
                    lock.failed = status != 0
                return status
        except ParameterError as err:
            print(f"{prog}: error: {_one_line(err)}", file=sys.stderr)
            return 2
        except KeyboardInterrupt as err:
            detail = _one_line(err)
            if received:
                name = signal.Signals(received[0]).name
                print(f"{prog}: terminated by {name}{': ' + detail if detail else ''}", file=sys.stderr)
                return 128 + received[0]
            print(f"{prog}: interrupted{': ' + detail if detail else ''}", file=sys.stderr)
            return 130
        except Exception as err:
            if os.environ.get("PMSMJAX_TRACEBACK"):
                raise
            where = f" ({err.filename})" if isinstance(err, OSError) and err.filename else ""
            if isinstance(err, OSError):
                print(f"{prog}: error: {err.strerror or _one_line(err)}{where}", file=sys.stderr)
                return 1
            print(
                f"{prog}: internal error: {type(err).__name__}: {_one_line(err)}; this is a bug, please "
                "report it with the command line (PMSMJAX_TRACEBACK=1 shows the traceback).",
                file=sys.stderr,
            )
            return 1


@contextlib.contextmanager
def _output_folder_held(args, command_line):
    """Hold the lock of the command's output folder (``args.out``) while it runs; yields the
    [`FolderLock`][pmsmjax.io.folder_lock.FolderLock], or None for a command without one. The folder is
    checked first (an existing file there is refused as by the command itself)."""
    out = getattr(args, "out", None)
    if out is None:
        yield None
        return
    from pmsmjax.cli.checks import output_folder
    from pmsmjax.io.folder_lock import held_folder

    with held_folder(output_folder(out), command_line) as lock:
        yield lock
