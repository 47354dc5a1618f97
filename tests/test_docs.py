"""The documentation site: it builds with ``mkdocs build --strict``, and the built site, opened
from disk in headless Chromium with every network request refused, loads every page without a
console error, finds pages with its search box, and links only to itself (or to the stated
external references below). Its generated pages come from the code: the CLI reference has
every command and option of the parser, the benchmarks page every script.

The API pages show the docstrings' Sphinx roles (``:func:`~a.b.f```) as cross-references to
the objects the pages render, and as inline code where no page renders the target
(``docs/sphinx_roles.py``).

The console blocks of the pages are run by ``tests/test_readme.py``.
"""

from __future__ import annotations

import argparse
import importlib
import os
import re
import subprocess
import sys
from pathlib import Path
from urllib.parse import unquote, urlparse

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: External addresses a page may link to (stated references; anything else is a failure):
#: the two formats the changelog follows.
ALLOWED_EXTERNAL: tuple[str, ...] = ("https://keepachangelog.com/en/1.1.0/",
                                     "https://semver.org/spec/v2.0.0.html")


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """The site built into a fresh folder with ``mkdocs build --strict`` (fails on any
    warning: a broken link, an unresolved reference, a docstring mkdocstrings cannot read)."""
    folder = tmp_path_factory.mktemp("site")
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1", "DISABLE_MKDOCS_2_WARNING": "true"}
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir",
                           str(folder)], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=900)
    assert done.returncode == 0, done.stderr[-5000:]
    return folder


def pages(site: Path) -> list[Path]:
    """Every page of the site but 404.html (a web server's error page: its links are
    root-relative, for the server's root, so it is no page to open from disk)."""
    return sorted(p for p in site.rglob("*.html") if p.relative_to(site).as_posix() != "404.html")


@pytest.fixture(scope="module")
def browser():
    """The report room's offline Chromium (the system's browser under Playwright, a fresh
    context): every request that is not file:, data:, blob: or about: is aborted and listed
    in ``browser.remote``."""
    from kinegrasp_env.toolkit.report.browser import OfflineChromium, find_chromium

    if find_chromium() is None:
        pytest.skip("the browser test needs Chromium (Debian: apt-get install chromium)")
    pytest.importorskip("playwright.sync_api")
    with OfflineChromium() as chromium:
        yield chromium


def open_page(browser, path: Path):
    """Open ``path``; (page, console errors, uncaught exceptions and failed local requests
    seen while it loaded)."""
    page, errors = browser.new_page()
    page.goto(path.as_uri(), wait_until="load")
    page.wait_for_timeout(150)  # scripts run after load (search worker, palette)
    return page, errors


def outside(url: str, site: Path) -> str | None:
    """Why ``url`` (absolute, as the browser resolved it) is not a reference into the site,
    or None when it is one (or an allowed external one)."""
    parsed = urlparse(url)
    if parsed.scheme in ("data", "javascript", "about", "blob") or url in ALLOWED_EXTERNAL:
        return None
    if parsed.scheme != "file":
        return "outside the site"
    target = Path(unquote(parsed.path))
    if not target.resolve().is_relative_to(site.resolve()):
        return "a file outside the site folder"
    if not target.exists():
        return "no such file in the site"
    return None


LINKS = ("() => [...document.querySelectorAll('a[href], link[href], script[src], img[src], "
         "iframe[src], source[src]')].map(e => e.href || e.src)")


@pytest.mark.expensive
def test_every_page_loads_without_console_errors_and_links_only_inside(site, browser):
    """Every page of the built site loads from disk with no console error, requests nothing
    off the machine, and every link, script, stylesheet and image it references is a file of
    the site (or a stated external reference)."""
    found = pages(site)
    assert len(found) >= 20, [p.name for p in found]
    problems = []
    for path in found:
        page, errors = open_page(browser, path)
        relative = path.relative_to(site)
        problems += [f"{relative}: {e}" for e in errors]
        for url in page.evaluate(LINKS):
            why = outside(url, site)
            if why:
                problems.append(f"{relative}: link {url}: {why}")
        page.close()
    problems += [f"request refused: {url}" for url in browser.remote]
    assert not problems, "\n".join(problems[:50])


@pytest.mark.expensive
def test_search_finds_pages(site, browser):
    """Typing into Material's search box lists results: pages of the site, the elbow guide
    among them for words of its subject."""
    page, errors = open_page(browser, site / "index.html")
    page.locator("input.md-search__input").click()
    page.keyboard.type("self-motion elbow", delay=30)
    page.wait_for_selector(".md-search-result__item", timeout=15000)
    hrefs = page.eval_on_selector_all(".md-search-result__item a", "els => els.map(e => e.href)")
    assert hrefs
    assert [outside(href, site) for href in hrefs] == [None] * len(hrefs), hrefs
    assert any("/guides/elbow.html" in href for href in hrefs), hrefs
    assert not errors, errors
    page.close()


def test_outside_rule():
    """The link rule on hand-made cases: a file of the site passes; the web, a file outside
    the folder and a missing file fail."""
    site = ROOT / "docs"
    assert outside((site / "conventions.md").as_uri(), site) is None
    assert outside("data:image/png;base64,AAAA", site) is None
    assert outside("https://example.org/", site) == "outside the site"
    assert outside((ROOT / "README.md").as_uri(), site) == "a file outside the site folder"
    assert outside((site / "nope.html").as_uri(), site) == "no such file in the site"


def _generated(name: str):
    """Run one of docs/gen_*.py with mkdocs-gen-files' ``open`` captured; {path: text}."""
    import importlib.util

    import mkdocs_gen_files

    written: dict[str, str] = {}

    class _Capture:
        def __init__(self, path, mode="w"):
            self.path, self.mode = path, mode

        def __enter__(self):
            return self

        def write(self, data):
            written[self.path] = written.get(self.path, "") + (
                data.decode() if isinstance(data, bytes) else data)

        def __exit__(self, *exc):
            return False

    original = mkdocs_gen_files.open
    mkdocs_gen_files.open = _Capture
    try:
        spec = importlib.util.spec_from_file_location(f"docs_{name}", ROOT / "docs" / name)
        spec.loader.exec_module(importlib.util.module_from_spec(spec))
    finally:
        mkdocs_gen_files.open = original
    return written


def test_cli_reference_has_every_command_and_option():
    """The generated CLI page names every sub-command (and nested sub-command) and every
    option string of the argparse parser (``-h/--help`` aside), walked here independently of
    the generator."""
    from kinegrasp_env.cli.main import build_parser

    text = _generated("gen_cli.py")["reference/cli.md"]
    missing = []

    def walk(parser, name):
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for sub, subparser in action.choices.items():
                    if f"## `{name} {sub}`" not in text:
                        missing.append(f"{name} {sub}")
                    walk(subparser, f"{name} {sub}")
            elif action.help != argparse.SUPPRESS and not isinstance(
                    action, argparse._HelpAction):  # -h/--help: on every command, said once
                missing.extend(f"{name} {s}" for s in action.option_strings
                               if f"`{s}`" not in text)

    walk(build_parser(), "kinegrasp")
    assert not missing, missing


def test_benchmarks_page_lists_every_script_and_renders_its_result():
    """Every benchmark script (a benchmarks/*.py that runs as a program) has a section and the
    modules they share have none; a script with a JSON result in benchmarks/results/ shows
    its figures (every top-level number of the file appears, as the generator formats it),
    one without says it was not run yet."""
    import json

    text = _generated("gen_benchmarks.py")["reference/benchmarks.md"]
    sections = {s.split("\n", 1)[0]: s for s in text.split("\n## ")[1:]}
    for script in sorted((ROOT / "benchmarks").glob("*.py")):
        if "__main__" not in script.read_text():
            assert script.stem not in sections, script.name
            continue
        assert script.stem in sections, script.name
        section = sections[script.stem]
        result = ROOT / "benchmarks" / "results" / f"{script.stem}.json"
        if not result.is_file():
            assert "Not run yet" in section, script.stem
            continue
        assert "Not run yet" not in section
        data = json.loads(result.read_text())
        numbers = [v for v in (data.values() if isinstance(data, dict) else [])
                   if isinstance(v, float)]
        for value in numbers:
            assert f"{value:.4g}" in section, (script.stem, value)


def test_ci_runs_the_readme_test_command_with_the_docs_build():
    """``.ci/run`` runs exactly the README's test command, and that command builds the site
    with ``mkdocs build --strict`` before pytest."""
    readme = (ROOT / "README.md").read_text()
    ci = [line for line in (ROOT / ".ci" / "run").read_text().splitlines()
          if "pytest" in line and not line.startswith("#")]
    assert len(ci) == 1, ci
    assert f"```bash\n{ci[0]}\n```" in readme, "the README's test command differs from .ci/run"
    build, tests = ci[0].find("mkdocs build --strict"), ci[0].find("-m pytest")
    assert 0 < build < tests, ci[0]


def docs_module(name: str):
    """A module of the docs tooling (``docs/<name>.py``), imported as the build imports it."""
    docs = str(ROOT / "docs")
    if docs not in sys.path:
        sys.path.insert(0, docs)
    return importlib.import_module(name)


#: A Sphinx role as a page would show it unconverted (its backticks rendered as <code>, or left).
RAW_ROLE = re.compile(r":(?:py:)?(?:func|class|mod|meth|data|attr|exc|obj|const):(?:`|<code>)")
#: A link mkdocs-autorefs resolved: (its attributes, its text).
AUTOREF = re.compile(r'<a ([^>]*class="autorefs[^"]*"[^>]*)>(.*?)</a>', re.DOTALL)


@pytest.mark.expensive
def test_api_pages_show_sphinx_roles_as_cross_references(site):
    """No page of the built site shows a raw Sphinx role; every cross-reference of the API
    pages lands on an element of the site (ferrari_canny's among them, a role of a quality
    docstring: quality.html, at the function's heading); and the objects the griffe extension
    links to are exactly the objects the API pages render (each heading id), so it neither
    links to a missing anchor nor leaves a rendered object unlinked."""
    raw = [f"{path.relative_to(site)}: {m.group()}" for path in pages(site)
           for m in RAW_ROLE.finditer(path.read_text())]
    assert not raw, raw[:20]

    api = sorted((site / "reference" / "api").glob("*.html"))
    assert len(api) >= 10, [p.name for p in api]
    ids = {path: set(re.findall(r'\bid="([^"]+)"', path.read_text())) for path in api}
    links, broken = [], []
    for path in api:
        for attributes, text in AUTOREF.findall(path.read_text()):
            href = re.search(r'href="([^"]*)"', attributes).group(1)
            file, _, anchor = href.partition("#")
            target = (path.parent / file).resolve() if file else path
            if anchor not in ids.get(target, ()):
                broken.append(f"{path.name}: {href}")
            links.append((target.name, anchor, text))
    assert not broken, broken[:20]
    assert ("quality.html", "kinegrasp_env.quality.epsilon.ferrari_canny",
            "<code>ferrari_canny</code>") in links

    rendered = {i for found in ids.values() for i in found
                if i == "kinegrasp_env" or i.startswith("kinegrasp_env.")}
    linked = set(docs_module("sphinx_roles").References.load().anchors.values())
    assert linked == rendered, (sorted(linked - rendered)[:20], sorted(rendered - linked)[:20])


@pytest.fixture(scope="module")
def toy_references():
    """The references of a small package read by griffe: ``pkg.mod``'s ``f`` and ``C`` (with
    its method ``m``) and ``pkg.room.a.h`` rendered, as the API pages render a room's exports;
    ``pkg.f`` and ``pkg.room.h`` lazy exports of them; ``pkg.other`` (no page), private,
    undocumented and imported names beside them."""
    import griffe

    sphinx_roles = docs_module("sphinx_roles")
    modules = {
        "__init__.py": '"""The package."""\n',
        "other.py": 'def helper():\n    """Helper."""\n',
        "room/__init__.py": '"""A room."""\n',
        "room/a.py": 'def h():\n    """H."""\n',
        "room/b.py": '"""Uses h."""\n',
        "mod.py": ('"""A module."""\nfrom pkg.other import helper\n\n\n'
                   'def f():\n    """F."""\n\n\ndef _g():\n    """G."""\n\n\n'
                   'def undocumented():\n    pass\n\n\n'
                   'class C:\n    """C."""\n\n    def m(self):\n        """M."""\n\n'
                   '    def _p(self):\n        """P."""\n'),
    }
    with griffe.temporary_visited_package("pkg", modules) as package:
        yield sphinx_roles.References(
            package, {"pkg": False, "pkg.mod.f": True, "pkg.mod.C": True, "pkg.room.a.h": True},
            {"pkg.f": "pkg.mod.f", "pkg.room.h": "pkg.room.a.h"})


@pytest.mark.parametrize(("scope", "content", "markdown"), [
    ("pkg.mod", "~pkg.mod.f", "[`f`][pkg.mod.f]"),
    ("pkg.mod", "pkg.mod.f", "[`pkg.mod.f`][pkg.mod.f]"),
    ("pkg.mod", "f", "[`f`][pkg.mod.f]"),                      # relative to the module
    ("pkg.mod", "f()", "[`f()`][pkg.mod.f]"),
    ("pkg.mod", "C.m", "[`C.m`][pkg.mod.C.m]"),
    ("pkg.mod.C", "m", "[`m`][pkg.mod.C.m]"),                  # relative to the class
    ("pkg.mod.C.m", "~C.m", "[`m`][pkg.mod.C.m]"),
    ("pkg.mod", "~pkg.mod.\n    f", "[`f`][pkg.mod.f]"),      # a target wrapped in the source
    ("pkg.other", "pkg.f", "[`pkg.f`][pkg.mod.f]"),           # a lazy export
    ("pkg.room.b", "h", "[`h`][pkg.room.a.h]"),               # a name its room exports
    ("pkg", ".m", "[`m`][pkg.mod.C.m]"),                      # the one object ending in .m
    ("pkg.mod", "the F <pkg.mod.f>", "[`the F`][pkg.mod.f]"),
    ("pkg", "pkg", "[`pkg`][pkg]"),
    ("pkg.mod", "!pkg.mod.f", "`pkg.mod.f`"),                 # Sphinx's "no link"
    ("pkg.mod", "_g", "`_g`"),                                # private: not rendered
    ("pkg.mod", "C._p", "`C._p`"),
    ("pkg.mod", "undocumented", "`undocumented`"),            # mkdocstrings skips it
    ("pkg.mod", "~pkg.other", "`other`"),                     # a module with no page
    ("pkg.mod", "helper", "`helper`"),                        # imported from pkg.other
    ("pkg.other", "f", "`f`"),                                # not in scope
    ("pkg.mod", "numpy.ndarray", "`numpy.ndarray`"),          # outside the package
    ("pkg.mod", "Engine.run", "`Engine.run`"),                # no such object
])
def test_role_becomes_a_link_to_a_rendered_object_or_inline_code(toy_references, scope,
                                                                  content, markdown):
    """A role's target resolves as Sphinx's Python domain resolves it (class, module, then
    absolute; ``.name`` by its unique suffix; here also the room's exports) and links only to
    an object the pages render;
    the displayed name follows Sphinx (``~``: the last component; ``title <target>``)."""
    assert toy_references.role(content, toy_references.find(scope)) == markdown


def test_markdown_rewrites_every_role_outside_code_blocks(toy_references):
    """Every role of a docstring is rewritten, with or without the ``py`` domain; a fenced
    code block is left as written."""
    text = ("Calls :func:`f` and :py:meth:`C.m`; see :mod:`pkg.other`.\n\n"
            "```text\n:func:`f`\n```\n")
    assert toy_references.markdown(text, toy_references.find("pkg.mod")) == (
        "Calls [`f`][pkg.mod.f] and [`C.m`][pkg.mod.C.m]; see `pkg.other`.\n\n"
        "```text\n:func:`f`\n```\n")
