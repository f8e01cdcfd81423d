"""The API reference as the reader gets it: the site built the way CI builds it (``mkdocs build --strict``),
then its HTML read back.

Checked: no Sphinx role (``:class:`` and the like) shows as text anywhere on the site; the docstrings' Google
``Args:`` sections render as mkdocstrings' parameter tables (``simulate`` and ``Scenario`` among them); every
cross-reference became a link whose page and anchor exist; and no API page is over :data:`MAX_PAGE_BYTES`.
"""

import html
import os
import re
import subprocess
import sys
import time
import zlib
from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
#: The largest API page, in bytes. A page carries the site's navigation and its own table of contents twice
#: (about 30 KB and 2 x 300 B per heading) besides its text; the largest module page is under 100 KB, and the
#: old package pages that rendered every module ran to 350 KB, unreadable and slow to load. 200 KB leaves
#: room for a module to grow and fails a page that renders a whole package again.
MAX_PAGE_BYTES = 200_000
ROLE = re.compile(r":(?:py:)?(class|func|meth|attr|data|mod|obj|exc):`?")
# An autoref that did not resolve is left as its Markdown source, "[title][identifier]".
UNRESOLVED = re.compile(r"\[[^\]\n]+\]\[[A-Za-z_][\w.]*\]")


def _text(page: str) -> str:
    page = re.sub(r"<(script|style)\b.*?</\1>", " ", page, flags=re.S | re.I)
    return html.unescape(re.sub(r"<[^>]+>", "", page))


def _inventory(site: Path) -> dict[str, str]:
    """Object name -> URL (page and anchor) from the site's objects.inv (Sphinx inventory, version 2)."""
    data = (site / "objects.inv").read_bytes()
    offset = 0
    for _ in range(4):
        offset = data.index(b"\n", offset) + 1
    urls = {}
    for line in zlib.decompress(data[offset:]).decode().splitlines():
        name, _domain_role, _priority, uri, *_ = line.split(" ")
        urls[name] = uri.replace("$", name) if uri.endswith("$") else uri
    return urls


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    site_dir = tmp_path_factory.mktemp("site")
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    start = time.perf_counter()
    result = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(site_dir)],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )
    seconds = time.perf_counter() - start
    assert result.returncode == 0, (
        f"mkdocs build --strict failed after {seconds:.1f} s:\n{result.stderr[-5000:]}"
    )
    print(f"mkdocs build --strict: {seconds:.1f} s")
    return site_dir


def _page(site: Path, url: str) -> Path:
    path = site / unquote(urlsplit(url).path)
    return path / "index.html" if url.endswith("/") or path.is_dir() else path


def _api_pages(site: Path) -> list[Path]:
    pages = sorted((site / "api").rglob("*.html"))
    assert len(pages) > 20, "the API reference has its pages"
    return pages


def test_no_sphinx_role_shows_as_text(site):
    found = []
    for page in sorted(site.rglob("*.html")):
        text = _text(page.read_text(encoding="utf-8"))
        for match in ROLE.finditer(text):
            found.append(
                f"{page.relative_to(site)}: ...{text[max(0, match.start() - 40) : match.end() + 40]!r}"
            )
    assert not found, f"{len(found)} raw Sphinx roles, e.g.:\n" + "\n".join(found[:20])


@pytest.mark.parametrize(
    ("name", "parameters"),
    [
        ("pmsmjax.simulate.simulate", ["drive", "scenario", "decimate", "initial_state"]),
        ("pmsmjax.scenarios.Scenario", ["speed_ref", "load_torque"]),
    ],
)
def test_parameter_tables(site, name, parameters):
    urls = _inventory(site)
    assert name in urls, f"{name} is not on the site"
    page = _page(site, urls[name]).read_text(encoding="utf-8")
    start = page.index(f'id="{name}"')
    # The object's entry runs to the next object's (its parameter table comes before its members).
    end = page.find('<div class="doc doc-object', start)
    end = end if end > 0 else len(page)
    entry = page[start:end]
    table = re.search(
        r'<span class="doc-section-title">Parameters:</span>.*?<table>(.*?)</table>', entry, re.S
    )
    assert table, f"no Parameters table in the entry of {name}"
    cells = re.findall(r"<td>\s*<code>(\w+)</code>\s*</td>", table.group(1))
    assert set(parameters) <= set(cells), f"{name}'s table lists {cells}, not all of {parameters}"


def test_cross_references_resolve(site):
    """No autoref left unresolved, and every internal link of the API pages leads to an existing anchor."""
    ids: dict[Path, set[str]] = {}
    links = 0
    broken = []
    for page in _api_pages(site):
        source = page.read_text(encoding="utf-8")
        assert "<autoref" not in source, f"{page.relative_to(site)} has an unprocessed <autoref>"
        text = _text(source)
        assert not UNRESOLVED.search(text), (
            f"{page.relative_to(site)}: unresolved cross-reference {UNRESOLVED.search(text).group(0)!r}"
        )
        for href, title in re.findall(
            r'<a class="autorefs autorefs-internal"[^>]*href="([^"]+)"[^>]*>(.{6})', source
        ):
            # A docstring's cross-reference shows a code title; a signature's annotations do not.
            links += title == "<code>"
            parts = urlsplit(html.unescape(href))
            target = (page.parent / unquote(parts.path)).resolve() if parts.path else page
            if target.is_dir() or not target.suffix:
                target = target / "index.html"
            if target not in ids:
                ids[target] = (
                    set(re.findall(r'\bid="([^"]+)"', target.read_text(encoding="utf-8")))
                    if target.is_file()
                    else set()
                )
            if not target.is_file() or (parts.fragment and unquote(parts.fragment) not in ids[target]):
                broken.append(f"{page.relative_to(site)} -> {href}")
    assert not broken, f"{len(broken)} links lead nowhere, e.g. {broken[:10]}"
    # The docstrings' cross-references became links: about 1,100 (the module tables give 160 of them).
    assert links > 1000, f"only {links} cross-reference links in the API pages' text"


def test_api_pages_are_small(site):
    sizes = {page.relative_to(site): page.stat().st_size for page in _api_pages(site)}
    over = {str(page): size for page, size in sizes.items() if size > MAX_PAGE_BYTES}
    assert not over, f"API pages over {MAX_PAGE_BYTES} bytes: {over}"


def test_equations_are_typeset(site):
    page = (site / "index.html").read_text(encoding="utf-8")
    assert "javascripts/mathjax.js" in page and "mathjax@3" in page, "MathJax is not loaded"
