"""The package's shape: layers that import one way only, and small modules.

core <- io <- ros <- experiment <- cli: a module may import its own layer and
the layers before it, never one after it.  core needs only numpy and the
standard library; only ros/ and the experiment runner import rclpy; only the
figure modules import matplotlib (lazily).  Read from the source with ast, so
nothing here imports the modules it checks.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "friction_sim"
LAYERS = ["core", "io", "ros", "experiment", "cli"]
RCLPY_USERS = {"ros", "experiment/runner.py"}
MATPLOTLIB_USERS = {"cli/figures.py", "cli/recording_figure.py"}
MODULES = sorted(PACKAGE.rglob("*.py"))


def imports(path: Path) -> set[str]:
    """Every module name ``path`` imports, at any depth (lazy imports count too)."""
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
    return names


def layer_of(path: Path) -> str | None:
    parts = path.relative_to(PACKAGE).parts
    return parts[0] if len(parts) > 1 and parts[0] in LAYERS else None


def where(path: Path) -> str:
    return path.relative_to(PACKAGE).as_posix()


@pytest.mark.parametrize("path", MODULES, ids=where)
def test_imports_point_one_way(path: Path) -> None:
    layer = layer_of(path)
    if layer is None:
        return
    allowed = set(LAYERS[:LAYERS.index(layer) + 1])
    for name in imports(path):
        parts = name.split(".")
        if parts[0] == "friction_sim" and len(parts) > 1 and parts[1] in LAYERS:
            assert parts[1] in allowed, f"{where(path)} ({layer}) imports {name}, a later layer"


@pytest.mark.parametrize("path", [p for p in MODULES if layer_of(p) == "core"], ids=where)
def test_core_needs_only_numpy_and_the_standard_library(path: Path) -> None:
    for name in imports(path):
        top = name.split(".")[0]
        assert top in ("numpy", "friction_sim") or top in sys.stdlib_module_names, f"{where(path)} imports {name}"


@pytest.mark.parametrize("path", MODULES, ids=where)
def test_rclpy_and_matplotlib_stay_where_they_belong(path: Path) -> None:
    tops = {name.split(".")[0] for name in imports(path)}
    relative = where(path)
    if "rclpy" in tops:
        assert relative.split("/")[0] in RCLPY_USERS or relative in RCLPY_USERS, f"{relative} imports rclpy"
    if "matplotlib" in tops:
        assert relative in MATPLOTLIB_USERS, f"{relative} imports matplotlib"


@pytest.mark.parametrize("path", MODULES, ids=where)
def test_every_module_stays_small(path: Path) -> None:
    lines = len(path.read_text().splitlines())
    assert lines <= 600, f"{where(path)} has {lines} lines: split it by concern"


def test_the_scipy_reference_is_not_installed_with_the_package() -> None:
    assert not (PACKAGE / "reference.py").exists()
    for path in MODULES:
        assert "scipy" not in {name.split(".")[0] for name in imports(path)}, where(path)
