"""Read the package's docstrings as the plain text they are written in, not as
reStructuredText: ``|x|`` is an absolute value, not a substitution; ``*`` a product, not
emphasis; a line indented under the one before it continues it.  autodoc hands each
docstring here (``autodoc-process-docstring``) before docutils parses it, so the API
reference builds without a warning and the docstrings stay written for people reading the
code.  Double-backtick literals are kept as they are.
"""

from __future__ import annotations

import re
from typing import Any

_LITERAL = re.compile(r"(``.+?``)")
_BULLET = re.compile(r"^\s*[-*] ")


def _escape(text: str) -> str:
    parts = _LITERAL.split(text)
    for i in range(0, len(parts), 2):  # outside ``...``
        part = parts[i].replace("\\", "\\\\").replace("|", "\\|").replace("*", "\\*")
        parts[i] = re.sub(r"(\w)_(?=\W|$)", r"\1\\_", part)  # name_ is not a reference
    return re.sub(r"::$", ":", "".join(parts))  # no literal block follows: the lines are flattened


def plain(lines: list[str]) -> list[str]:
    """``lines`` of a plain-text docstring as reStructuredText that says the same."""
    out: list[str] = []
    paragraph: list[str] = []

    def flush() -> None:
        if not paragraph:
            return
        bullets = any(_BULLET.match(line) for line in paragraph)
        for line in paragraph:
            stripped = _escape(line.strip())
            if bullets and _BULLET.match(line):
                out.append("- " + stripped[2:].lstrip() if not stripped.startswith("\\*") else "- " + stripped[3:])
            elif bullets and out and out[-1].startswith(("- ", "  ")):
                out.append("  " + stripped)
            else:
                out.append(stripped)
        paragraph.clear()

    for line in lines:
        if line.strip():
            if _BULLET.match(line) and paragraph and not _BULLET.match(paragraph[0]):
                flush()
                out.append("")
            paragraph.append(line)
        else:
            flush()
            out.append("")
    flush()
    return out


def _process(app: Any, what: str, name: str, obj: Any, options: Any, lines: list[str]) -> None:
    lines[:] = plain(lines)


def setup(app: Any) -> dict[str, Any]:
    app.connect("autodoc-process-docstring", _process)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
