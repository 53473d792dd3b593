"""How close each numeric test sits to its tolerance: a pytest plugin for ``make margins``.

A test that passes with its error at 90 % of its tolerance on one CPU fails on
the next (other BLAS kernels, other SIMD paths in NumPy).  This plugin records,
for every passing comparison, the ratio error / tolerance:

* ``pytest.approx`` (scalars, sequences and arrays: they all compare through
  ``ApproxScalar``), ``numpy.allclose``, ``numpy.isclose``,
  ``numpy.testing.assert_allclose`` and ``math.isclose``;
* plain ``assert error <= tolerance`` (and <, >=, >) through pytest's
  ``pytest_assertion_pass`` hook, where both sides are numbers (or simple
  arithmetic of numbers) and the tolerance side is small (|tol| < 1e-3): the
  shape of a hand-written tolerance check.

Enabled with ``-p margins_plugin -o enable_assertion_pass_hook=true`` and
``MARGINS_OUT=file.json``; at the end it writes {test id: [ratio, where]}
with the largest ratio each test reached.  ``bench/margins.py`` runs the
numeric tests under several CPU settings and merges the files.  It changes no
result: every wrapped function returns what the original returns.
"""

from __future__ import annotations

import ast
import inspect
import json
import math
import operator
import os
import re
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest

#: test id -> (largest ratio error/tolerance seen, where)
_WORST: dict[str, tuple[float, str]] = {}
_CURRENT: list[str] = [""]
_SMALL_TOLERANCE = 1e-3


def _record(ratio: float, where: str) -> None:
    test = _CURRENT[0]
    if not test or not math.isfinite(ratio):
        return
    if ratio > _WORST.get(test, (-1.0, ""))[0]:
        _WORST[test] = (ratio, where)


def _caller() -> str:
    """file:line of the test code that made the comparison."""
    frame = inspect.currentframe()
    while frame is not None:
        name = frame.f_code.co_filename
        if "/test/" in name and not name.endswith("margins_plugin.py"):
            return f"{os.path.relpath(name)}:{frame.f_lineno}"
        frame = frame.f_back
    return "?"


def _array_ratio(actual: Any, desired: Any, rtol: float, atol: float) -> float:
    try:
        a = np.atleast_1d(np.asarray(actual, dtype=float))
        b = np.atleast_1d(np.asarray(desired, dtype=float))
        error = np.abs(a - b)
        bound = np.broadcast_to(atol + rtol * np.abs(b), error.shape)
        finite = np.isfinite(error) & np.isfinite(bound)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(bound[finite] > 0, error[finite] / bound[finite], np.where(error[finite] > 0, np.inf, 0))
        return float(ratio.max()) if ratio.size else 0.0
    except (TypeError, ValueError, IndexError):  # never let the survey change a test's outcome
        return math.nan


def _wrap_close(module: Any, name: str, rtol_default: float, atol_default: float, *, records_on_fail: bool) -> None:
    original: Callable[..., Any] = getattr(module, name)

    def wrapped(a: Any, b: Any, *args: Any, **kwargs: Any) -> Any:
        result = original(a, b, *args, **kwargs)  # raises for assert_allclose: nothing to record then
        rtol = kwargs.get("rtol", args[0] if len(args) > 0 else rtol_default)
        atol = kwargs.get("atol", args[1] if len(args) > 1 else atol_default)
        if records_on_fail or bool(np.all(result)):
            _record(_array_ratio(a, b, rtol, atol), _caller())
        return result

    setattr(module, name, wrapped)


def _install_wrappers() -> None:
    from _pytest.approx import ApproxScalar

    compare = ApproxScalar.__eq__

    def approx_eq(self: Any, actual: Any) -> bool:
        result: bool = compare(self, actual)
        if result:
            try:
                tolerance = float(self.tolerance)
                error = abs(float(self.expected) - float(actual))
                _record(error / tolerance if tolerance > 0 else (0.0 if error == 0 else math.inf), _caller())
            except (TypeError, ValueError, OverflowError):
                pass
        return result

    ApproxScalar.__eq__ = approx_eq  # type: ignore[method-assign]
    _wrap_close(np, "allclose", 1e-5, 1e-8, records_on_fail=False)
    _wrap_close(np, "isclose", 1e-5, 1e-8, records_on_fail=False)
    _wrap_close(np.testing, "assert_allclose", 1e-7, 0.0, records_on_fail=True)
    original_isclose = math.isclose

    def isclose(a: float, b: float, *, rel_tol: float = 1e-9, abs_tol: float = 0.0) -> bool:
        result = original_isclose(a, b, rel_tol=rel_tol, abs_tol=abs_tol)
        if result:
            bound = max(rel_tol * max(abs(a), abs(b)), abs_tol)
            _record(abs(a - b) / bound if bound > 0 else 0.0, _caller())
        return result

    math.isclose = isclose


_NUMBER = re.compile(r"np\.(?:float64|float32|int64|int32)\(([^()]*)\)")
_OPS: dict[type, Callable[[Any, Any], Any]] = {
    ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul, ast.Div: operator.truediv,
    ast.Pow: operator.pow}


def _number(text: str) -> float | None:
    """The value of a numeric literal or simple arithmetic of literals (None otherwise)."""
    try:
        node = ast.parse(_NUMBER.sub(r"\1", text.strip()), mode="eval").body
        return float(_evaluate(node))
    except (SyntaxError, ValueError, TypeError, ZeroDivisionError, OverflowError, RecursionError):
        return None


def _evaluate(node: ast.AST) -> float:
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) and not isinstance(node.value, bool):
        return float(node.value)
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        value = _evaluate(node.operand)
        return -value if isinstance(node.op, ast.USub) else value
    if isinstance(node, ast.BinOp) and type(node.op) in _OPS:
        return float(_OPS[type(node.op)](_evaluate(node.left), _evaluate(node.right)))
    raise ValueError("not arithmetic")


_COMPARISON = re.compile(r"^(.*?)\s(<=|<|>=|>)\s(.*)$")


def pytest_assertion_pass(item: pytest.Item, lineno: int, orig: str, expl: str) -> None:
    """A passing ``assert error <= tolerance``: record error/tolerance."""
    first = expl.split("\n", 1)[0]
    match = _COMPARISON.match(first)
    if match is None:
        return
    left, op, right = _number(match.group(1)), match.group(2), _number(match.group(3))
    if left is None or right is None:
        return
    error, tolerance = (left, right) if op in ("<", "<=") else (right, left)
    if tolerance == 0.0 or abs(tolerance) >= _SMALL_TOLERANCE or error * tolerance < 0.0:
        return
    where = f"{os.path.relpath(str(item.path))}:{lineno}"
    if _CURRENT[0] == item.nodeid:
        _record(error / tolerance, where)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_call(item: pytest.Item) -> Iterator[None]:
    _CURRENT[0] = item.nodeid
    yield
    _CURRENT[0] = ""


def pytest_configure(config: pytest.Config) -> None:
    _install_wrappers()


def pytest_sessionfinish(session: pytest.Session) -> None:
    path = os.environ.get("MARGINS_OUT")
    if path:
        with open(path, "w", encoding="utf-8") as out:
            json.dump({test: [ratio if math.isfinite(ratio) else 1e300, where]
                       for test, (ratio, where) in sorted(_WORST.items())}, out, indent=0)


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    """A failed test is past its tolerance: recorded as an infinite ratio."""
    if report.failed:
        _WORST[report.nodeid] = (math.inf, f"failed in {report.when}")
