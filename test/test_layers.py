"""The package's shape: layers that import one way only, no circles, and small modules.

core <- io <- ros <- experiment <- cli: a module may import its own layer and
the layers before it, never one after it; inside core the same holds for its
parts (model <- physics <- engine <- meanspeed <- control <- runtime).  io
holds formats, files and sinks: it may use core's types and formulas but never
its simulators (engine, runtime); re-simulation lives in experiment.  No
import circle anywhere, not even inside a sub-package (lazy imports count:
they only hide a circle).  core needs only numpy, Numba (in the compiled
engine alone, which the nodes never import) and the standard library; only
ros/ and the experiment runner import rclpy; only the figure modules import
matplotlib (lazily).  Read from the source with ast, so nothing here imports
the modules it checks (but the one test that the nodes load without Numba).
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "friction_sim"
LAYERS = ["core", "io", "ros", "experiment", "cli"]
CORE_PARTS = ["model", "physics", "engine", "meanspeed", "control", "runtime"]
NUMBA_USERS = {"core/engine/compiled.py", "core/engine/transient_kernel.py"}
RCLPY_USERS = {"ros", "experiment/runner.py"}
MATPLOTLIB_USERS = {"cli/figures.py", "cli/recording_figure.py"}
MODULES = sorted(PACKAGE.rglob("*.py"))


def imports(path: Path) -> set[str]:
    """Every module name ``path`` imports, at any depth (lazy imports count too);
    ``from package import name`` counts as importing package.name where that is a module."""
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
            names.update(f"{node.module}.{alias.name}" for alias in node.names
                         if module_path(f"{node.module}.{alias.name}") is not None)
    return names


def module_path(name: str) -> Path | None:
    """The source file of a friction_sim module (a package: its __init__.py), else None."""
    parts = name.split(".")
    if parts[0] != "friction_sim":
        return None
    base = PACKAGE.joinpath(*parts[1:])
    for candidate in (base.with_suffix(".py"), base / "__init__.py"):
        if candidate.is_file():
            return candidate
    return None


def import_graph() -> dict[Path, set[Path]]:
    """Module -> the friction_sim modules it imports."""
    graph: dict[Path, set[Path]] = {}
    for path in MODULES:
        targets = {module_path(name) for name in imports(path)}
        graph[path] = {target for target in targets if target is not None and target != path}
    return graph


def circles(graph: dict[Path, set[Path]]) -> list[list[Path]]:
    """The strongly connected components with more than one module (Tarjan): each holds a circle."""
    index: dict[Path, int] = {}
    low: dict[Path, int] = {}
    stack: list[Path] = []
    found: list[list[Path]] = []

    def visit(node: Path) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        for target in graph.get(node, ()):
            if target not in index:
                visit(target)
                low[node] = min(low[node], low[target])
            elif target in stack:
                low[node] = min(low[node], index[target])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


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


#: Modules a layer must not import although they come before it: io runs no simulation.
SIMULATORS = ("friction_sim.core.engine", "friction_sim.core.runtime")
NO_SIMULATION = {"io"}


def runs_a_simulator(name: str) -> bool:
    """Whether importing module ``name`` brings in a simulator: the engine or a runtime."""
    return any(name == simulator or name.startswith(simulator + ".") for simulator in SIMULATORS)


@pytest.mark.parametrize("path", [p for p in MODULES if layer_of(p) in NO_SIMULATION], ids=where)
def test_io_holds_formats_files_and_sinks_and_runs_no_simulation(path: Path) -> None:
    for name in imports(path):
        assert not runs_a_simulator(name), \
            f"{where(path)} ({layer_of(path)}) imports {name}, a simulator: re-simulation belongs in experiment"


def test_the_simulation_check_finds_a_simulator() -> None:
    assert runs_a_simulator("friction_sim.core.engine") and runs_a_simulator("friction_sim.core.runtime.realtime")
    assert not runs_a_simulator("friction_sim.core.model.params") and not runs_a_simulator("friction_sim.core.engines")


def core_part(path: Path) -> str | None:
    parts = path.relative_to(PACKAGE).parts
    return parts[1] if len(parts) > 2 and parts[0] == "core" and parts[1] in CORE_PARTS else None


@pytest.mark.parametrize("path", [p for p in MODULES if core_part(p)], ids=where)
def test_core_parts_import_one_way(path: Path) -> None:
    part = core_part(path)
    assert part is not None
    allowed = set(CORE_PARTS[:CORE_PARTS.index(part) + 1])
    for name in imports(path):
        parts = name.split(".")
        if parts[:2] == ["friction_sim", "core"] and len(parts) > 2 and parts[2] in CORE_PARTS:
            assert parts[2] in allowed, f"{where(path)} (core/{part}) imports {name}, a later part of core"


def test_there_is_no_import_circle() -> None:
    found = circles(import_graph())
    assert not found, "import circles: " + "; ".join(" <-> ".join(where(p) for p in c) for c in found)


def test_the_circle_check_finds_a_circle() -> None:
    a, b, c = PACKAGE / "a.py", PACKAGE / "b.py", PACKAGE / "c.py"
    assert circles({a: {b}, b: {c}, c: {a}}) == [[a, b, c]] and circles({a: {b}, b: set(), c: {a}}) == []


@pytest.mark.parametrize("path", [p for p in MODULES if layer_of(p) == "core"], ids=where)
def test_core_needs_only_numpy_numba_and_the_standard_library(path: Path) -> None:
    for name in imports(path):
        top = name.split(".")[0]
        assert top in ("numpy", "friction_sim") or top in sys.stdlib_module_names or (
            top == "numba" and where(path) in NUMBA_USERS), f"{where(path)} imports {name}"


def test_the_nodes_and_the_single_slider_load_without_numba() -> None:
    """Nothing compiles when a node starts: Numba is imported by the population engine alone."""
    import subprocess

    code = ("import sys, friction_sim.ros.slider, friction_sim.ros.controller, friction_sim.core.engine.single; "
            "print('numba' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "False"


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


#: The one module that uses SciPy: calibration's bounded least squares (imported inside the function).
SCIPY_USERS = {"experiment/calibration.py"}


def test_the_scipy_reference_is_not_installed_with_the_package() -> None:
    """The exactness tests' SciPy references stay in test/; the package itself
    uses SciPy only for calibration's least squares, lazily."""
    assert not (PACKAGE / "reference.py").exists()
    for path in MODULES:
        if "scipy" in {name.split(".")[0] for name in imports(path)}:
            assert path.relative_to(PACKAGE).as_posix() in SCIPY_USERS, where(path)
