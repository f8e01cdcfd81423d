"""The README and the documentation site say what the code does: every ``pmsmjax`` command line they show
parses with the real parser (its subcommand, flags and choices exist), the README's Python runs, its
relative links lead to files, and it stays short enough to read.

The parser is :func:`pmsmjax.cli.build_parser`, the one ``pmsmjax`` itself uses; parsing alone checks
flags and choices without running anything (argument types that read files do not exist in it).
"""

import contextlib
import io
import re
import shlex
from pathlib import Path

import jax
import pytest

from pmsmjax.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
DOC_PAGES = sorted((ROOT / "docs").rglob("*.md"))
README_MAX_LINES = 200

#: The two set-up commands the README opens with, word for word.
SETUP_COMMANDS = (
    "python3 -m venv .venv && . .venv/bin/activate && pip install -e . && pmsmjax demo --out demo_out",
    'python3 -m venv .venv && . .venv/bin/activate && pip install -e ".[test]" && python -m pytest',
)

FENCE = re.compile(r"^```(\w*)[^\n]*\n(.*?)^```", re.S | re.M)
SHELL_LANGUAGES = {"bash", "sh", "shell", "console", ""}
INLINE_CODE = re.compile(r"`(pmsmjax [^`]+)`")
#: A word that stands for what the user fills in (``DIR``, ``NAME``, ``CMD``): an inline mention that
#: names the subcommand so is a pattern, not a command line.
PLACEHOLDER = re.compile(r"^[A-Z][A-Z_]*$")
SHELL_OPERATORS = {"&&", "||", ";", "|", ">", ">>", "2>&1"}


def fenced_blocks(text: str, languages) -> list[str]:
    return [body for lang, body in FENCE.findall(text) if lang in languages]


def shell_lines(block: str) -> list[str]:
    """The logical lines of a shell block: ``\\``-continued lines joined, prompts (``$ ``) dropped."""
    joined = re.sub(r"\\\n\s*", " ", block)
    return [line.strip().removeprefix("$ ") for line in joined.splitlines() if line.strip()]


def pmsmjax_arguments(line: str) -> list[str] | None:
    """The arguments after ``pmsmjax`` (or ``python -m pmsmjax``) in a shell line, up to the next shell
    operator; None when the line does not run pmsmjax."""
    words = shlex.split(line, comments=True)
    if "pmsmjax" not in words:
        return None
    rest = words[words.index("pmsmjax") + 1 :]
    ends = [i for i, w in enumerate(rest) if w in SHELL_OPERATORS]
    return rest[: ends[0]] if ends else rest


def command_lines(text: str) -> list[tuple[list[str], bool]]:
    """Every pmsmjax command of a Markdown text as ``(arguments, is_mention)``: the shell blocks' lines
    (whole commands), then the inline code spans (mentions, which may leave out required arguments)."""
    found = []
    for block in fenced_blocks(text, SHELL_LANGUAGES):
        found += [(a, False) for a in map(pmsmjax_arguments, shell_lines(block)) if a is not None]
    for span in INLINE_CODE.findall(FENCE.sub("", text)):
        words = shlex.split(span.replace("\\|", "|"))[1:]
        if words and not PLACEHOLDER.match(words[0]):  # `pmsmjax CMD --help`: a pattern, not a command
            found.append((words, True))
    return [(variant, mention) for words, mention in found for variant in variants(words)]


def variants(words: list[str]) -> list[list[str]]:
    """The concrete command lines a documented one stands for: ``[--optional parts]`` included, each of
    the ``a|b|c`` alternatives once (the others at their first), and a placeholder value (``--n N``,
    ``--estimator NAME``) replaced by the flag's first choice, else by ``1``."""
    words = [w.strip("[]") for w in words if w.strip("[]")]
    subcommand = subparsers().get(words[0]) if words else None
    options = subcommand._option_string_actions if subcommand else {}
    for i in range(1, len(words)):
        action = options.get(words[i - 1])
        if PLACEHOLDER.match(words[i]) and action is not None:
            words[i] = str(next(iter(action.choices))) if action.choices else "1"
    choices = [w.split("|") if "|" in w and not w.startswith("-") else [w] for w in words]
    return [[c[k] if k < len(c) else c[0] for c in choices] for k in range(max(map(len, choices), default=1))]


def subparsers() -> dict:
    actions = [a for a in build_parser()._actions if a.choices and isinstance(a.choices, dict)]
    return actions[0].choices


#: What a mention in prose may leave out: the required arguments, or a flag's value.
MENTION_GAPS = ("the following arguments are required", "expected one argument")


def parse_error(arguments: list[str], mention: bool = False) -> str | None:
    """None when ``pmsmjax ARGUMENTS`` parses (``--help`` included), else the parser's one line."""
    err = io.StringIO()
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
            build_parser().parse_args(arguments)
    except SystemExit as stop:
        message = err.getvalue().strip() or f"exit {stop.code}"
        if stop.code == 0 or (mention and any(gap in message for gap in MENTION_GAPS)):
            return None
        return message
    return None


def test_readme_is_short():
    n = len(README.read_text().splitlines())
    assert n <= README_MAX_LINES, f"README.md has {n} lines, over {README_MAX_LINES}: move detail to docs/"


def test_readme_opens_with_the_setup_commands():
    blocks = [b.strip() for b in fenced_blocks(README.read_text(), {"bash"})]
    assert tuple(blocks[:2]) == SETUP_COMMANDS


@pytest.mark.parametrize("page", [README, *DOC_PAGES], ids=lambda p: str(p.relative_to(ROOT)))
def test_every_command_line_parses(page):
    text = page.read_text()
    failures = {" ".join(a): e for a, mention in command_lines(text) if (e := parse_error(a, mention))}
    assert not failures, "\n".join(f"pmsmjax {cmd}: {e}" for cmd, e in failures.items())


def test_the_command_finder_sees_commands_and_refusals():
    """The checks above can fail: a made-up flag and a made-up choice are refused, alternatives expand,
    placeholders take a valid value, and a mention may leave out what a whole command may not."""
    text = (
        "```bash\npmsmjax demo --out d \\\n  --no-such-flag 1 && ls\npmsmjax identify LOG --out D "
        "[--pole-pairs N]\n```\n`pmsmjax demo --control pi\\|nope` and `pmsmjax observe`"
    )
    commands = command_lines(text)
    assert commands == [
        (["demo", "--out", "d", "--no-such-flag", "1"], False),
        (["identify", "LOG", "--out", "1", "--pole-pairs", "1"], False),
        (["demo", "--control", "pi"], True),
        (["demo", "--control", "nope"], True),
        (["observe"], True),
    ]
    assert [parse_error(*c) is None for c in commands] == [False, True, True, False, True]
    assert parse_error(["observe"]) is not None  # a whole command must give what is required
    assert command_lines(README.read_text())[0] == (["demo", "--out", "demo_out"], False)


def test_readme_relative_links_lead_to_files():
    targets = re.findall(r"\]\(([^)\s]+)\)|src=\"([^\"]+)\"", README.read_text())
    links = [a or b for a, b in targets]
    relative = [t.split("#")[0] for t in links if not re.match(r"^(https?:|mailto:|#)", t)]
    assert relative, "the README links into the docs"
    missing = [t for t in relative if not (ROOT / t).exists()]
    assert not missing, f"README.md links to missing files: {missing}"


#: getting_started's batch-gradient block compiles a vmap'd forward-mode scan: about 5 s on 2 CPU cores.
PYTHON_PAGES = [
    "README.md",
    pytest.param("docs/getting_started.md", marks=pytest.mark.slow),
    "docs/guides/your_drive.md",
]


@pytest.mark.parametrize("page", PYTHON_PAGES)
def test_python_blocks_run(page):
    """Each block runs on its own, in this process (so programs compiled by one are reused by the next),
    in float32 as a reader runs it (the suite's float64 is switched off for the block)."""
    for block in fenced_blocks((ROOT / page).read_text(), {"python"}):
        with jax.enable_x64(False), contextlib.redirect_stdout(io.StringIO()):
            exec(compile(block, page, "exec"), {"__name__": "__docs__"})
