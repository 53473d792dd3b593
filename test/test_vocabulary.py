"""One dimensionless vocabulary: the model's groups and 2*pi are written in one module.

phi = Fd/(mu*m*g), a = Pa/(m*g), Gamma = Pa/(m*g*cos(alpha)), U = V*f/(g*mu),
their inverses and 2*pi live in :mod:`friction_sim.core.model.dimensionless`;
everywhere else calls them.  This test reads the source of the package and the
benches with ast (nothing here imports what it checks) and fails on an inline
copy outside that module:

* a 2*pi literal: a product of the number 2 and pi (``2.0 * math.pi``,
  ``math.pi * 2``, ``f * 2 * np.pi``), ``math.tau``, a number within a
  thousandth of 2*pi (``6.283``), or TWO_PI imported from elsewhere;
* a division by a weight or a load (``x / params.weight``, ``x / (m * g)``,
  ``x / load``): a force in units of the weight, a or Gamma; with mu in the
  divisor too, phi;
* a division by g*mu, or a product of g and mu: U from V, or V from U;
* the inverses: a product of mu, a weight and a third factor (phi*mu*m*g), or
  of a weight and a factor named as a ratio (``a * weight``,
  ``gamma * params.normal_weight``, ``given["throw_number"] * weight``).

Names decide what a factor is (mu; weight, normal_weight, load; mass or m with
gravity or g; ratio, phi, gamma, a, throw_number): the package spells its
quantities so.  The detector is tested on snippets below, both ways, so a check
that finds nothing is known to be able to find something.
"""

from __future__ import annotations

import ast
import math
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: The one module where the groups and 2*pi are written out.
HOME = "friction_sim/core/model/dimensionless.py"
HOME_MODULE = "friction_sim.core.model.dimensionless"
SOURCES = sorted([*(ROOT / "friction_sim").rglob("*.py"), *(ROOT / "bench").rglob("*.py")])

#: Inline copies allowed: (file, the line's text, kind).  None: the vocabulary is called everywhere.
ALLOWED: set[tuple[str, str, str]] = set()

MU = {"mu"}
LOADS = {"weight", "normal_weight", "load"}
MASSES = {"mass", "m"}
GRAVITIES = {"gravity", "g", "effective_gravity"}
RATIO = re.compile(r"(^|_)(ratio|ratios|phi|gamma|a)(_|$)|throw_number")
#: Calls that leave the quantity they wrap as it is (a conversion, a magnitude).
WRAPPERS = {"float", "abs", "asarray", "array", "astype"}
TWO_PI = 2.0 * math.pi  # the number this test looks for (a test may write it; the package may not)


def identity(node: ast.AST) -> str | None:
    """The name a factor goes by: a variable, an attribute (params.mu: mu), a
    column (columns["mu"]: mu), through conversions (float(x), x.astype(float));
    None for anything else (a sum, another call, a number)."""
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        return node.attr
    if isinstance(node, ast.Subscript):
        key = node.slice
        if isinstance(key, ast.Constant) and isinstance(key.value, str):
            return key.value
        return identity(node.value)
    if isinstance(node, ast.Call):
        func = node.func
        name = func.id if isinstance(func, ast.Name) else func.attr if isinstance(func, ast.Attribute) else None
        if name == "astype" and isinstance(func, ast.Attribute):
            return identity(func.value)
        if name in WRAPPERS and node.args:
            return identity(node.args[0])
    return None


def factors(node: ast.AST) -> list[ast.AST]:
    """The factors of a product, through parentheses and signs (a*(b*c): a, b, c)."""
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Mult):
        return factors(node.left) + factors(node.right)
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        return factors(node.operand)
    return [node]


def divisors(node: ast.BinOp) -> list[ast.AST]:
    """The factors a division divides by: x/(a*b) and x/a/b both give a, b."""
    found = factors(node.right)
    if isinstance(node.left, ast.BinOp) and isinstance(node.left.op, ast.Div):
        found += divisors(node.left)
    return found


def names(nodes: list[ast.AST]) -> set[str]:
    return {name for name in map(identity, nodes) if name is not None}


def has_load(found: set[str]) -> bool:
    """A weight or a load among the names: weight, normal_weight, load, or a mass with a gravity."""
    return bool(found & LOADS) or bool(found & MASSES and found & GRAVITIES)


def is_two(node: ast.AST) -> bool:
    return isinstance(node, ast.Constant) and not isinstance(node.value, bool) and node.value == 2


def is_pi(node: ast.AST) -> bool:
    return isinstance(node, (ast.Name, ast.Attribute)) and identity(node) == "pi"


def two_pi_literal(node: ast.AST) -> bool:
    """2*pi spelled out, not as TWO_PI from the vocabulary (a product is judged whole, at its top)."""
    if isinstance(node, ast.Attribute):
        return node.attr == "tau" and identity(node.value) in {"math", "np", "numpy"}
    if isinstance(node, ast.ImportFrom):
        taken = {alias.name for alias in node.names}
        return (node.module == "math" and "tau" in taken) or (node.module != HOME_MODULE and "TWO_PI" in taken)
    if isinstance(node, ast.Constant):
        return isinstance(node.value, float) and abs(node.value - TWO_PI) <= 1e-3 * TWO_PI
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Mult):
        chain = factors(node)
        return any(map(is_two, chain)) and any(map(is_pi, chain))
    return False


def product_kind(chain: list[ast.AST]) -> str | None:
    """What a product (not a divisor) writes inline: V from U, an inverse of phi, of a or of Gamma."""
    found = names(chain)
    if found & MU and has_load(found) and len(chain) >= 3:
        return "phi inverse"
    if found & MU and found & GRAVITIES:
        return "U <-> V"
    if has_load(found) and any(RATIO.search(name) for name in found - LOADS - MASSES - GRAVITIES):
        return "ratio inverse"
    return None


def division_kind(node: ast.BinOp) -> str | None:
    """What a division writes inline: phi, U, or a force over a weight (a, Gamma)."""
    under = names(divisors(node))
    if under & MU and has_load(under):
        return "phi"
    if under & MU and under & GRAVITIES:
        return "U <-> V"
    if has_load(under):
        return "force / weight"
    return None


def inline_groups(source: str) -> list[tuple[int, str]]:
    """(line, kind) of every inline copy of a dimensionless group or of 2*pi in ``source``."""
    tree = ast.parse(source)
    products = [node for node in ast.walk(tree) if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Mult)]
    inner = {id(child) for node in products for child in (node.left, node.right)  # judged with their product
             if isinstance(child, ast.BinOp) and isinstance(child.op, ast.Mult)}
    below = {id(node.right) for node in ast.walk(tree)  # judged with their division
             if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Div)}
    found: set[tuple[int, str]] = set()
    for node in ast.walk(tree):
        if id(node) in inner:
            continue
        if two_pi_literal(node):
            found.add((getattr(node, "lineno", 0), "2*pi"))
        kind = None
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Mult) and id(node) not in below:
            kind = product_kind(factors(node))
        elif isinstance(node, ast.BinOp) and isinstance(node.op, ast.Div):
            kind = division_kind(node)
        if kind is not None:
            found.add((node.lineno, kind))
    return sorted(found)


def where(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


def hits(path: Path) -> set[tuple[str, str, str]]:
    """(file, the line's text, kind) of every inline copy in ``path``."""
    source = path.read_text()
    lines = source.splitlines()
    return {(where(path), lines[line - 1].strip(), kind) for line, kind in inline_groups(source)}


@pytest.mark.parametrize("path", [p for p in SOURCES if where(p) != HOME], ids=where)
def test_no_inline_group_or_two_pi(path: Path) -> None:
    """Outside the vocabulary module every group and 2*pi is a call or an import of it."""
    found = hits(path) - ALLOWED
    assert not found, f"inline copies (call or import {HOME_MODULE} instead):\n" + "\n".join(
        f"{file}: {kind}: {line}" for file, line, kind in sorted(found))


def test_the_allow_list_holds_only_what_is_there() -> None:
    """Each allowed copy is still in its file (else its entry goes)."""
    present = set().union(*(hits(ROOT / file) for file in {file for file, _, _ in ALLOWED}))
    assert not ALLOWED - present, f"stale allow-list entries: {sorted(ALLOWED - present)}"


def test_the_vocabulary_module_is_where_the_groups_are_written() -> None:
    """The home module writes them out, so the detector run on it finds each kind."""
    kinds = {kind for _, kind in inline_groups((ROOT / HOME).read_text())}
    assert kinds >= {"2*pi", "phi", "phi inverse", "force / weight", "ratio inverse", "U <-> V"}, kinds


@pytest.mark.parametrize("snippet, kind", [
    ("omega = 2.0 * math.pi * f", "2*pi"),
    ("omega = f * 2 * np.pi", "2*pi"),
    ("period = math.pi * 2 / omega", "2*pi"),
    ("x = -2.0 * numpy.pi", "2*pi"),
    ("x = phase / (2.0 * math.pi)", "2*pi"),
    ("x = math.tau * f", "2*pi"),
    ("from math import tau", "2*pi"),
    ("from friction_sim.core.physics.roots import NEVER, TWO_PI", "2*pi"),
    ("x = 6.283185307179586 * f", "2*pi"),
    ("x = theta % 6.2832", "2*pi"),
    ("phi = inputs.drive_force / (params.mu * params.weight)", "phi"),
    ("phi = fd / (mu * mass * gravity)", "phi"),
    ("phi = fd / mu / (m * g)", "phi"),
    ("phi = ft / (params.mu * load)", "phi"),
    ("phi = fd / (columns['mu'].astype(float) * weight)", "phi"),
    ("a = inputs.excitation_amplitude / params.weight", "force / weight"),
    ("a = pa / (m * g)", "force / weight"),
    ("gamma = pa / params.normal_weight", "force / weight"),
    ("fd = phi * params.mu * params.weight", "phi inverse"),
    ("fd = given['drive_ratio'] * (columns['mu'].astype(float) * weight)", "phi inverse"),
    ("fd = float(phi_arr[i]) * params.mu * weight", "phi inverse"),
    ("pa = a * params.weight", "ratio inverse"),
    ("pa = gamma * params.normal_weight", "ratio inverse"),
    ("pa = given['throw_number'] * weight * cos(x)", "ratio inverse"),
    ("pa = max_ratio * model.weight", "ratio inverse"),
    ("u = v * f / (g * mu)", "U <-> V"),
    ("u = v * f / (params.gravity * params.mu)", "U <-> V"),
    ("v = u * model.gravity * model.mu / f", "U <-> V"),
])
def test_the_detector_finds_an_inline_copy(snippet: str, kind: str) -> None:
    assert [found for _, found in inline_groups(snippet)] == [kind]


@pytest.mark.parametrize("snippet", [
    "x = 2.0 * theta", "x = math.pi - 2.0 * theta", "x = 4.0 * math.pi ** 2", "x = math.pi / 2",
    "omega = TWO_PI * f", "from friction_sim.core.model.dimensionless import TWO_PI", "x = 2 * pi_half",
    "x = 6.0", "x = 2.0 * math.e", "x = tau * omega",
    "friction = mu * normal", "limit = p.mu * normal_impulse", "margin = excess - mu * least_load",
    "b1 = (0.0 + mu * pa) / m", "acc = force / p.mass", "n0 = weight * cos_degrees(alpha) - fz",
    "pull = abs(fd - params.downhill_weight)", "w = mass * gravity", "friction_force = mu * weight",
    "phi = drive_ratio(fd, mu, weight)", "x = weights / total",
])
def test_the_detector_leaves_other_arithmetic_alone(snippet: str) -> None:
    assert inline_groups(snippet) == []
