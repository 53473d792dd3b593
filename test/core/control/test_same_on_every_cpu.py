"""The resonant inner loop decides the same bits on every CPU (issue 29: the
same scenario, the same numbers).

OpenBLAS loads the kernels of the CPU it finds (``DYNAMIC_ARCH``): SkylakeX
with AVX-512 here, Haswell on a machine without it, older ones elsewhere, and
they round differently.  While the lock-in's fit went through LAPACK's
least squares and the plan through ``numpy.linalg.solve``, acceptance_7's
lockstep recording had one digest with SkylakeX's kernels, another with
Haswell's and a third with Prescott's: the "same" run on another machine was
another run.  So each setting below runs the core's closed loop (the exact
resonant slider, its accelerometer with noise, the lock-in, the drive loop
with tracking, the outer law: test_drive.closed_loop) in a fresh interpreter,
and the decisions must be the same bits as with the kernels OpenBLAS chose
for this machine."""

from __future__ import annotations

import os
import platform
import subprocess
import sys
from pathlib import Path

import pytest

#: The most generic OpenBLAS kernel of each machine (it runs on every CPU of that kind).
_GENERIC_KERNEL = {"x86_64": "Prescott", "AMD64": "Prescott", "aarch64": "ARMV8", "arm64": "ARMV8"}

_LOOP = """
import hashlib, importlib.util, sys
spec = importlib.util.spec_from_file_location("test_drive", sys.argv[1])
module = importlib.util.module_from_spec(spec)
sys.modules["test_drive"] = module
spec.loader.exec_module(module)
run = module.closed_loop(60, {0: 3e-4, 20: 1e-4}, noise=0.6, tracking=True, delay=0.25)
print(hashlib.sha256(repr((run.level, run.frequency, run.speed, run.per_drive)).encode()).hexdigest())
"""


def _decisions(environment: dict[str, str]) -> str:
    """The digest of a closed loop's decisions, run with ``environment`` added."""
    done = subprocess.run([sys.executable, "-c", _LOOP, str(Path(__file__).with_name("test_drive.py"))],
                          env={**os.environ, **environment}, capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stderr
    return done.stdout.strip()


def test_the_inner_loop_decides_the_same_bits_with_the_most_generic_blas_kernel() -> None:
    kernel = _GENERIC_KERNEL.get(platform.machine())
    if kernel is None:
        pytest.skip(f"no generic OpenBLAS kernel is known for a {platform.machine()} machine")
    chosen = _decisions({})
    assert len(chosen) == 64
    assert _decisions({"OPENBLAS_CORETYPE": kernel}) == chosen
