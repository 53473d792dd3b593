"""Sphinx configuration of friction_sim's documentation (rosdoc2's layout: doc/ beside
package.xml, rosdoc2.yaml at the package root).

``make docs`` builds it with warnings as errors into build/docs/html.  The pages are
Markdown (myst-parser); the CLI reference comes from the parsers (sphinx-argparse), the
API from the docstrings (autodoc), the node tables from the spec (checked by
test/core/model/test_spec.py), and the model's figures are drawn at build time by the
package's own figure functions (doc/_ext/demo_figures.py), never committed.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))
sys.path.insert(0, str(HERE.parent))  # the package of this checkout, installed or not
os.environ.setdefault("MPLBACKEND", "Agg")

project = "friction_sim"
author = "friction_sim maintainers"
copyright = "friction_sim maintainers, Apache-2.0"
release = "0.1.0"

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.viewcode",
    "sphinxarg.ext",
    "demo_figures",
    "plain_docstrings",
]
source_suffix = {".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "_ext"]
myst_enable_extensions = ["dollarmath", "colon_fence"]
myst_heading_anchors = 3
# Fences the docs use for commands the suite checks (test/cli/test_readme.py) rather than
# highlights: "sh ros2", "sh cluster" are shell lines.
highlight_language = "text"
suppress_warnings = ["misc.highlighting_failure"]

autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": True}
autodoc_typehints = "description"
autodoc_member_order = "bysource"
nitpicky = False

html_theme = "alabaster"
html_title = "friction_sim"
html_theme_options = {"description": "An exact stick-slip simulator of a vibratory feeder, for ROS 2 Jazzy",
                      "fixed_sidebar": True}
