"""The bound on glibc's arenas a node process sets before its threads start (friction_sim.ros.heap)."""

from __future__ import annotations

import os
import subprocess
import sys

ASK = "from friction_sim.ros.heap import limit_heap_arenas; print(limit_heap_arenas())"


def ask(env: dict[str, str]) -> str:
    done = subprocess.run([sys.executable, "-c", ASK], capture_output=True, text=True, env=env, timeout=60,
                          check=False)
    assert done.returncode == 0, done.stderr
    return done.stdout.strip()


def test_a_process_bounds_its_arenas_unless_the_user_chose_a_bound() -> None:
    """On glibc (this platform) the bound is set; a MALLOC_ARENA_MAX in the environment is the
    user's choice, and glibc's own reading of it stands."""
    env = {key: value for key, value in os.environ.items() if key != "MALLOC_ARENA_MAX"}
    assert ask(env) == "True"
    assert ask(env | {"MALLOC_ARENA_MAX": "4"}) == "False"


def test_the_entry_points_bound_the_arenas_before_anything_runs() -> None:
    """``friction-sim`` and the node executables (run_node) call it first thing."""
    import inspect

    from friction_sim.cli import main
    from friction_sim.ros import run

    for entry in (main.main, run.run_node):
        body = inspect.getsource(entry)
        assert body.index("limit_heap_arenas()") < min(
            index for index in (body.find("rclpy.init"), body.find("build_parser()")) if index >= 0)
