"""Draw the figures the model page shows, at build time, with the package's own CLI.

The pictures `make demo` writes to out/ are generated files and never committed; the
documentation draws the same ones, with the same commands (``friction-sim trace``,
``umap``, ...), into doc/_generated/ (git-ignored) when the build starts, so a page
always shows what this checkout computes.  A command that fails fails the build.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

#: file name -> the ``friction-sim`` arguments that draw it (as ``make demo`` and the README give them)
FIGURES: dict[str, list[str]] = {
    "fig2.png": ["trace"],
    "umap.png": ["umap", "--grid", "101"],
    "flight.png": ["trace", "--angle", "30", "--mu", "0.5", "--amplitude", "20", "--drive-force", "0"],
    "conveyor.png": ["conveyor"],
    "resonance.png": ["resonance", "--natural-frequency", "52", "--from", "40", "--to", "60"],
    "reduction.png": ["reduction"],
}
GENERATED = "_generated"


def draw(target: Path) -> None:
    """Draw every figure of FIGURES into ``target`` (each command's CSV beside it)."""
    import contextlib
    import io

    from friction_sim.cli.main import main

    target.mkdir(parents=True, exist_ok=True)
    for name, arguments in FIGURES.items():
        with contextlib.redirect_stdout(io.StringIO()):
            code = main([*arguments, "--png", str(target / name)])
        if code != 0 or not (target / name).is_file():
            raise RuntimeError(f"friction-sim {' '.join(arguments)} --png {name}: exit code {code}")


def _builder_inited(app: Any) -> None:
    draw(Path(app.srcdir) / GENERATED)


def setup(app: Any) -> dict[str, Any]:
    app.connect("builder-inited", _builder_inited)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
