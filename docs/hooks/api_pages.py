"""MkDocs hook: the API reference, one page per package plus one per module, laid out from the source tree.

A page of the navigation names its package with a marker line, ``<!-- api-modules: PACKAGE -->`` (optionally
``only: NAME NAME ...`` to keep some of its modules, in that order). The hook replaces the line with the
package's docstring (``::: PACKAGE`` without members: a package's re-exports are its modules' objects, each
documented once, on its module's page) and a table of the modules with the first sentence of each docstring,
each linking to a page of its own, ``api/MODULE.md``, that the hook generates (a subpackage gets a package
page the same way). Modules whose name starts with ``_`` are private and left out.

Why a page per module: a package page that renders all its modules runs to hundreds of kilobytes (the
estimators', over 350 KB); a module's page stays small. The module pages are out of the navigation (the
package pages' tables lead to them), so the navigation every page carries does not grow with them. The
layout is read from the files, so the pages follow modules that move.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

from mkdocs.structure.files import File

_MARKER = re.compile(
    r"^<!--\s*api-modules:\s*(?P<package>[\w.]+)(?:\s+only:(?P<only>[\w\s]+?))?\s*-->\s*$", re.M
)
# The first sentence ends at a full stop followed by a space and a capital (or at the paragraph's end), not
# after the usual abbreviations.
_SENTENCE_END = re.compile(
    r"(?<!\be\.g)(?<!\bi\.e)(?<!\bcf)(?<!\bvs)(?<!\bFig)(?<!\bEq)(?<!\bch)\.(?=\s+[A-Z(`\[]|\s*$)"
)
_FOLDER = "api"


def _root(config) -> Path:
    return Path(config["config_file_path"]).resolve().parent


def _source(root: Path, dotted: str) -> Path | None:
    base = root.joinpath(*dotted.split("."))
    if (base / "__init__.py").is_file():
        return base / "__init__.py"
    if base.with_suffix(".py").is_file():
        return base.with_suffix(".py")
    return None


def _is_package(root: Path, dotted: str) -> bool:
    source = _source(root, dotted)
    return source is not None and source.name == "__init__.py"


def _summary(path: Path) -> str:
    doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or ""
    paragraph = " ".join(doc.strip().split("\n\n", 1)[0].split())
    match = _SENTENCE_END.search(paragraph)
    sentence = paragraph[: match.end()] if match else paragraph
    return sentence.replace("|", "\\|")


def _modules(root: Path, package: str, only: list[str] | None) -> list[str]:
    if only is not None:
        names = only
    else:
        folder = root.joinpath(*package.split("."))
        names = [
            child.stem if child.suffix == ".py" else child.name
            for child in sorted(folder.iterdir())
            if not child.name.startswith("_")
            and (child.suffix == ".py" or (child.is_dir() and (child / "__init__.py").is_file()))
        ]
    for name in names:
        if _source(root, f"{package}.{name}") is None:
            raise FileNotFoundError(f"api-modules: no module {package}.{name} under {root}")
    return [f"{package}.{name}" for name in names]


def _markers(text: str):
    for match in _MARKER.finditer(text):
        only = match.group("only")
        yield match, match.group("package"), (only.split() if only else None)


def _package_block(root: Path, package: str, only: list[str] | None) -> str:
    out = [f"::: {package}", "    options:", "      show_root_heading: false", "      members: false", ""]
    rows = [
        f"| [`{dotted}`][{dotted}] | {_summary(_source(root, dotted))} |"
        for dotted in _modules(root, package, only)
    ]
    if rows:
        out += ["| Module | Summary |", "| --- | --- |", *rows, ""]
    return "\n".join(out)


def _module_page(root: Path, dotted: str) -> str:
    if _is_package(root, dotted):
        return f"# {dotted}\n\n<!-- api-modules: {dotted} -->\n"
    return f"# {dotted}\n\n::: {dotted}\n    options:\n      show_root_heading: false\n"


def on_files(files, config):
    """Add a generated page for every module (and subpackage) that a marker's package lists."""
    root = _root(config)
    pending = []
    for file in files.documentation_pages():
        if file.src_uri.startswith(f"{_FOLDER}/") and file.abs_src_path:
            text = Path(file.abs_src_path).read_text(encoding="utf-8")
            pending += [(package, only) for _, package, only in _markers(text)]
    done = set()
    while pending:
        package, only = pending.pop(0)
        for dotted in _modules(root, package, only):
            if dotted in done:
                continue
            done.add(dotted)
            files.append(File.generated(config, f"{_FOLDER}/{dotted}.md", content=_module_page(root, dotted)))
            if _is_package(root, dotted):
                pending.append((dotted, None))
    return files


def on_page_markdown(markdown, page, config, files):  # noqa: ARG001 (MkDocs' hook signature)
    """Replace each marker with its package's docstring and module table."""
    root = _root(config)
    return _MARKER.sub(
        lambda m: _package_block(root, m.group("package"), next(_markers(m.group(0)))[2]), markdown
    )
