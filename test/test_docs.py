"""The documentation site builds, with warnings as errors, as `make docs` builds it.

A cross-reference to a page or heading that is gone, a ``--help`` that argparse cannot
format (the CLI reference is drawn from the parsers), a docstring that does not parse or a
figure command that fails each fail the build, and so this test.  The site's commands are
run by test/cli/test_readme.py.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
PAGES = ("getting_started", "model", "tutorials/ros", "tutorials/experiments", "tutorials/record_replay",
         "tutorials/calibrate", "tutorials/resonance", "tutorials/sweeps", "tutorials/foxglove",
         "tutorials/offline", "reference/cli", "reference/nodes", "reference/api", "architecture", "benchmarks")


def test_the_site_builds_without_a_warning(tmp_path: Path) -> None:
    out = tmp_path / "html"
    done = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
                           "-d", str(tmp_path / "doctrees"), "doc", str(out)],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout[-5000:] + done.stderr[-5000:]
    front = (out / "index.html").read_text()
    for page in PAGES:
        assert (out / f"{page}.html").is_file(), page
        assert f'href="{page}.html"' in front, f"the front page's contents do not list {page}"
    cli = (out / "reference" / "cli.html").read_text()
    assert all(verb in cli for verb in ("calibrate", "experiment", "sweep", "slider", "controller", "feeder"))
    model = (out / "model.html").read_text()
    assert model.count("<img") >= 4, "the model page shows the demo's figures"


def test_rosdoc2_finds_the_sphinx_project() -> None:
    """rosdoc2.yaml as rosdoc2 parses it: two documents, the Sphinx builder on doc/ (conf.py there)."""
    attic, config = yaml.safe_load_all((ROOT / "rosdoc2.yaml").read_text())
    assert attic == {"type": "rosdoc2 config", "version": 1}
    sphinx = [builder["sphinx"] for builder in config["builders"] if "sphinx" in builder]
    assert sphinx and sphinx[0]["sphinx_sourcedir"] == "doc" and (ROOT / "doc" / "conf.py").is_file()
    assert config["settings"]["python_source"] == "friction_sim"
