"""Where the compiled population engine keeps its code, and what it says while compiling.

The package may be installed read-only (a colcon install, a system prefix):
compiled code goes to the user's cache, keyed by the sources and the Numba
version, or to the temporary directory when that cannot be written; never next
to the sources.  The first call in a fresh cache says on the caller's progress
line that it compiles, and when it is done."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import friction_sim
from friction_sim.core.engine import compiled
from friction_sim.core.engine.population import run_batch

PACKAGE = Path(friction_sim.__file__).parent


def cache_directory_in(env: dict[str, str], cwd: Path | None = None) -> Path:
    """The cache directory a fresh process chooses under ``env`` (the choice is made at import)."""
    done = subprocess.run(
        [sys.executable, "-c", "from friction_sim.core.engine import compiled; print(compiled.CACHE_DIR)"],
        capture_output=True, text=True, env=env, timeout=120, check=False, cwd=cwd)
    assert done.returncode == 0 and "Traceback" not in done.stderr, done.stderr
    return Path(done.stdout.strip().splitlines()[-1])


def clean_env(**values: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "XDG_CACHE_HOME")}
    return env | values


def test_the_cache_is_the_users_keyed_by_the_sources(tmp_path: Path) -> None:
    chosen = cache_directory_in(clean_env(XDG_CACHE_HOME=str(tmp_path / "xdg")))
    assert chosen.parent == tmp_path / "xdg" / "friction_sim" / "numba"
    assert chosen.name == compiled.cache_directory().name, "the same sources and Numba: the same key"
    assert cache_directory_in(clean_env(NUMBA_CACHE_DIR=str(tmp_path / "own"))).parent == tmp_path / "own"


def test_two_copies_of_the_sources_keep_their_code_apart(tmp_path: Path) -> None:
    """Numba takes a source of another modification time for a changed one: a second checkout
    (or an install beside the sources) sharing the directory would recompile each time the
    other had run.  The key holds where the sources lie."""
    import shutil

    shutil.copytree(PACKAGE, tmp_path / "copy" / "friction_sim", ignore=shutil.ignore_patterns("__pycache__"))
    env = clean_env(XDG_CACHE_HOME=str(tmp_path / "xdg"))
    here = cache_directory_in(env)
    there = cache_directory_in(env | {"PYTHONPATH": str(tmp_path / "copy")}, cwd=tmp_path)  # (not this checkout's)
    assert here.parent == there.parent and here.name != there.name


def test_an_unwritable_user_cache_falls_back_to_the_temporary_directory(tmp_path: Path) -> None:
    """A cache 'directory' below a plain file cannot be made, even by root (file
    permissions would not stop root): the temporary directory serves instead."""
    blocker = tmp_path / "a_file"
    blocker.write_text("not a directory")
    env = clean_env(XDG_CACHE_HOME=str(blocker / "cache"), TMPDIR=str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    chosen = cache_directory_in(env)
    assert chosen.parent == tmp_path / "tmp" / f"friction_sim-numba-{os.getuid()}"
    assert chosen.is_dir()


def test_compiled_code_is_never_written_beside_the_sources() -> None:
    """Whatever ran before in this session (test_batch compiles or loads the engine):
    nothing compiled lies in the package, so a read-only install works."""
    compiled.prepare()
    assert compiled.CACHE_DIR.resolve() not in PACKAGE.resolve().parents
    assert not any(PACKAGE.rglob("*.nbi")) and not any(PACKAGE.rglob("*.nbc"))
    assert compiled.cached() and any(compiled.CACHE_DIR.rglob("*.nbc"))


def test_a_call_that_compiles_says_so_on_its_progress_line(monkeypatch: pytest.MonkeyPatch) -> None:
    """The message comes from whether the cache holds the engine: a cache that
    does not (seen as such here) makes run_batch say it compiles, where to, and
    when it is done; a cache that does says nothing."""
    values = {"excitation_amplitude": np.array([4.0, 5.0, 6.0])}
    lines: list[str] = []
    monkeypatch.setattr(compiled, "cached", lambda: False)
    run_batch(values, settle_periods=1, periods=2, progress=lines.append)
    assert len(lines) == 2 and lines[0].startswith("compiling the population engine"), lines
    assert str(compiled.CACHE_DIR) in lines[0] and lines[1].startswith("population engine compiled in")
    monkeypatch.setattr(compiled, "cached", lambda: True)
    lines.clear()
    run_batch(values, settle_periods=1, periods=2, progress=lines.append)
    assert lines == []
