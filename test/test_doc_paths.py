"""The docs name only files and modules that exist.

A README that names ``core/meanspeed.py`` after it became a package sends a
reader to nothing.  Every path-like name in the Markdown docs (README.md and
doc/) is resolved against the tree: ``x/y.py`` must be a file, ``x/y`` a
folder or a module (``io/recordwriter.record_messages`` names a module's
function), looked for from the repository, the package, test/ and bench/.
Paths inside an installed layout (``install/.../share/friction_sim/...``) and
templates (``friction_sim/numba/<key>``) are not the tree's, so not checked.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = sorted([ROOT / "README.md", *(ROOT / "doc").rglob("*.md")])
BASES = (ROOT, ROOT / "friction_sim", ROOT / "test", ROOT / "bench")
#: A path of the tree: starts at the package or one of its layers, not inside a longer path.
PATH = re.compile(r"(?<![\w/.$~-])((?:friction_sim|core|io|ros|experiment|cli|test|bench)(?:/[A-Za-z_][\w]*)+/?"
                  r"(?:\.py)?)(?![\w<])")


def named_paths(text: str) -> set[str]:
    """The tree paths ``text`` names (see the module docstring)."""
    found = set()
    for match in PATH.finditer(text):
        path = match.group(1)
        if text[match.end():match.end() + 2].lstrip("/").startswith("<"):
            continue  # a template: friction_sim/numba/<key>
        found.add(path.rstrip("/"))
    return found


def exists(path: str) -> bool:
    """Whether ``path`` is a file, a folder or a module of the tree (from any of BASES)."""
    return any((base / path).exists() or (base / f"{path}.py").is_file() for base in BASES)


def test_the_detector_finds_paths_and_leaves_install_paths_and_templates() -> None:
    text = ("see `core/meanspeed.py` and io/recordwriter.record_messages, `friction_sim/cli`; "
            "install/friction_sim/share/friction_sim/config/slider.yaml; `friction_sim/numba/<key>`")
    assert named_paths(text) == {"core/meanspeed.py", "io/recordwriter", "friction_sim/cli"}
    assert not exists("core/meanspeed.py") and exists("io/recordwriter") and exists("friction_sim/cli")


@pytest.mark.parametrize("doc", DOCS, ids=lambda doc: str(doc.relative_to(ROOT)))
def test_every_path_the_docs_name_exists(doc: Path) -> None:
    missing = sorted(path for path in named_paths(doc.read_text()) if not exists(path))
    assert not missing, f"{doc.name} names paths that do not exist: {missing}"


#: A Markdown link to a file of the tree: [text](path) or [text](path#anchor), not a URL.
LINK = re.compile(r"\]\((?!https?://|mailto:|#)([^)#\s]+)(?:#[^)]*)?\)")


@pytest.mark.parametrize("doc", DOCS, ids=lambda doc: str(doc.relative_to(ROOT)))
def test_every_link_of_the_docs_reaches_a_file(doc: Path) -> None:
    """The README links into the site (doc/*.md), which GitHub shows as it is; the site's own
    links Sphinx checks too (-W), this checks them as files for a reader of the repository."""
    broken = sorted(target for target in LINK.findall(doc.read_text()) if not (doc.parent / target).exists())
    assert not broken, f"{doc.name} links to what does not exist: {broken}"
