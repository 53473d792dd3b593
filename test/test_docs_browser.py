"""The built site, opened in a headless browser as a reader opens it.

test/test_docs.py proves that Sphinx builds the site without a warning; this proves that a
browser shows it whole: the front page loads with no console error, its title and top
heading are the project's, every image loads (natural width > 0), and every link into the
site reaches a file that exists (and, for a ``#fragment``, an element with that id).

The browser is tools/docs-browser: Chromium from the npm package @sparticuz/chromium,
driven by puppeteer-core, installed by `make browser` (`npm ci` there), which `make suite`
(and so `make test` and CI) runs first.  It is not optional: without it these tests fail
and say how to install it.

The site is built here from a copy of doc/: the build draws its figures into the source
folder (doc/_generated/), and test/test_docs.py builds the site at the same time on the
other pytest worker; two builds writing one PNG could hand one of them half a file.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any
from urllib.parse import unquote, urlsplit

import pytest

ROOT = Path(__file__).resolve().parents[1]
BROWSER_DIR = ROOT / "tools" / "docs-browser"
CHROMIUM = BROWSER_DIR / "node_modules" / ".chromium" / "chromium"
#: the model page shows the demo's figures: where the image check has images to check
PAGES_WITH_IMAGES = ("model",)


def _conf(name: str) -> str:
    """A string setting of doc/conf.py (``name = "..."``), read, not executed (it edits sys.path)."""
    found = re.search(rf'^{name} = "([^"]*)"$', (ROOT / "doc" / "conf.py").read_text(), re.MULTILINE)
    assert found, f"doc/conf.py sets no {name}"
    return found.group(1)


def _front_heading() -> str:
    """The front page's top heading as doc/index.md writes it."""
    return (ROOT / "doc" / "index.md").read_text().splitlines()[0].removeprefix("# ").strip()


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The site built as `make docs` builds it (warnings as errors), from a copy of doc/."""
    node = shutil.which("node")
    assert node, "no node on PATH: the docs browser (tools/docs-browser) runs on Node.js"
    assert CHROMIUM.is_file(), (f"no headless Chromium at {CHROMIUM.relative_to(ROOT)}: "
                                "`make browser` installs it (npm ci in tools/docs-browser); `make suite` does")
    work = tmp_path_factory.mktemp("site")
    shutil.copytree(ROOT / "doc", work / "doc", ignore=shutil.ignore_patterns("_generated"))
    # doc/conf.py puts the folder above it on sys.path, which is the copy's: this checkout's
    # package comes first instead.
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, (str(ROOT), os.environ.get("PYTHONPATH"))))}
    done = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
                           "-d", str(work / "doctrees"), str(work / "doc"), str(work / "html")],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout[-5000:] + done.stderr[-5000:]
    return work / "html"


def open_page(page: Path, shot: Path) -> dict[str, Any]:
    """What tools/docs-browser/shot.mjs reports of ``page`` (its screenshot saved to ``shot``)."""
    done = subprocess.run(["node", str(BROWSER_DIR / "shot.mjs"), str(page), str(shot), "--json"],
                          capture_output=True, text=True, timeout=180)
    # 1 is a page with findings (the report says which, and the tests below judge them);
    # anything else is the browser failing to open it.
    assert done.returncode in (0, 1), done.stdout[-3000:] + done.stderr[-3000:]
    report: dict[str, Any] = json.loads(done.stdout)
    return report


@pytest.fixture(scope="module")
def front(site: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The front page as the browser shows it."""
    return open_page(site / "index.html", tmp_path_factory.mktemp("shot") / "front.png")


def _png_size(path: Path) -> tuple[int, int]:
    """Width and height from a PNG's header (its IHDR chunk)."""
    head = path.read_bytes()[:24]
    assert head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR", f"{path} is not a PNG"
    return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")


def test_the_front_page_loads_with_no_console_error(front: dict[str, Any]) -> None:
    assert front["consoleErrors"] == []
    assert front["pageErrors"] == []
    assert front["failedRequests"] == []
    width, height = _png_size(Path(front["screenshot"]))
    # a full-page screenshot: the viewport's width, at least its height
    assert width == front["viewport"]["width"] and height >= front["viewport"]["height"]


def test_the_front_page_is_the_projects(front: dict[str, Any]) -> None:
    project = _conf("project")
    assert _front_heading() == project, "doc/index.md's heading names the project"
    assert front["topHeading"] == project
    # Sphinx's title: the page's heading, then the site's html_title
    assert front["title"] == f"{project} \u2014 {_conf('html_title')}"


def test_every_link_into_the_site_reaches_a_file(front: dict[str, Any], site: Path) -> None:
    internal = [link for link in front["links"] if urlsplit(link["href"]).scheme == "file"]
    # the front page's contents: at least each page of its toctree
    assert len(internal) >= 6, front["links"]
    for link in internal:
        parts = urlsplit(link["href"])
        target = Path(unquote(parts.path))
        assert target.is_file(), f"{link['text']!r} -> {link['href']}: no such file"
        assert target.resolve().is_relative_to(site.resolve()), f"{link['href']} leaves the site"
        if parts.fragment:
            assert f'id="{unquote(parts.fragment)}"' in target.read_text(), \
                f"{link['text']!r} -> {link['href']}: no element with that id"


@pytest.mark.parametrize("page", ("index", *PAGES_WITH_IMAGES))
def test_every_image_loads(page: str, site: Path, tmp_path: Path) -> None:
    report = open_page(site / f"{page}.html", tmp_path / f"{page}.png")
    assert report["consoleErrors"] == [] and report["failedRequests"] == []
    if page in PAGES_WITH_IMAGES:
        assert len(report["images"]) >= 4, "the model page shows the demo's figures"
    for image in report["images"]:
        assert image["naturalWidth"] > 0 and image["naturalHeight"] > 0, f"{image['src']} did not load"
