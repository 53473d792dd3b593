"""Run the numeric tests under several CPU settings and list the tightest margins.

``make margins`` (or ``python test/margins_survey.py [pytest args]``) runs the
tests once per setting below with :mod:`margins_plugin`, which records for
each test the largest error / tolerance ratio it reached, and prints every
test whose worst ratio over all settings is above 0.1 (a margin under 10x),
with the ratio under each setting.  A ratio that moves between settings is a
result that depends on the CPU: its tolerance must cover that (see the
comments at the tolerances).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
#: NumPy's AVX-512 dispatch targets: their names changed in NumPy 2.4 ("X86_V4").
_AVX512 = ("X86_V4 AVX512_ICL AVX512_SPR" if tuple(int(p) for p in np.__version__.split(".")[:2]) >= (2, 4)
           else "AVX512F AVX512CD AVX512_SKX AVX512_CLX AVX512_CNL AVX512_ICL AVX512_SPR")
#: name -> environment changes: OpenBLAS's kernels (inside solve_ivp, lstsq, ...) and NumPy's SIMD paths.
SETTINGS: dict[str, dict[str, str]] = {
    "default": {},
    "Haswell": {"OPENBLAS_CORETYPE": "Haswell"},
    "SkylakeX": {"OPENBLAS_CORETYPE": "SkylakeX"},
    "Sandybridge": {"OPENBLAS_CORETYPE": "Sandybridge"},
    "no-AVX512": {"NPY_DISABLE_CPU_FEATURES": _AVX512},
}
#: Tests whose numbers come from NumPy, SciPy and the core (the ROS tests publish the same core's numbers).
NUMERIC = ["test/core", "test/io", "test/experiment", "test/cli"]
REPORT_ABOVE = 0.1


def run(name: str, changes: dict[str, str], args: list[str], out: Path) -> dict[str, tuple[float, str]]:
    """One pytest run under ``changes``; the worst ratio per test."""
    # PYTHONPYCACHEPREFIX: fresh bytecode, since the hook needs the asserts rewritten with it on
    env = {**os.environ, **changes, "MARGINS_OUT": str(out), "PYTHONPYCACHEPREFIX": str(out.parent / "pycache")}
    command = [sys.executable, "-m", "pytest", "-q", "-rf", "-p", "margins_plugin", "-p", "no:cacheprovider",
               "-o", "enable_assertion_pass_hook=true", *args]
    done = subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True)
    lines = done.stdout.strip().splitlines()
    tail = lines[-1:] or ["(no output)"]
    print(f"{name:12s} {tail[0]}", flush=True)
    for line in lines:  # a failure is named, not only counted
        if line.startswith(("FAILED ", "ERROR ")):
            print(f"{'':12s} {line}", flush=True)
    data = json.loads(out.read_text()) if out.exists() else {}
    return {test: (float(ratio), str(where)) for test, (ratio, where) in data.items()}


def main(argv: list[str]) -> int:
    args = argv or NUMERIC
    with tempfile.TemporaryDirectory() as tmp:
        results = {name: run(name, changes, args, Path(tmp) / f"{name}.json") for name, changes in SETTINGS.items()}
    tests = sorted({test for result in results.values() for test in result})
    worst = {test: max(result.get(test, (0.0, ""))[0] for result in results.values()) for test in tests}
    tight = sorted((test for test in tests if worst[test] > REPORT_ABOVE), key=lambda t: -worst[t])
    print(f"\n{len(tests)} tests compared numbers; {len(tight)} reached more than {REPORT_ABOVE:g} of a tolerance:")
    print("  ".join(f"{name:>11s}" for name in SETTINGS) + "  test (where)")
    for test in tight:
        ratios = "  ".join(f"{results[name].get(test, (0.0, ''))[0]:11.3g}" for name in SETTINGS)
        where = next(r[test][1] for r in results.values() if test in r and r[test][0] == worst[test])
        print(f"{ratios}  {test} ({where})")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
