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


def test_a_run_s_collections_leave_what_existed_before_it_alone_and_hand_it_back_after() -> None:
    """A collection of the oldest generation walks every object: after start-up, ~80 ms stopped
    in a run.  Within run_heap what existed before is frozen (never walked), what the run
    makes is collected as always, and at the end the collector has it all again."""
    import gc

    from friction_sim.ros.heap import RUN_YOUNG_THRESHOLD, run_heap

    class Cycle:
        def __init__(self) -> None:
            self.me = self

    before = Cycle()
    interpreters = gc.get_freeze_count()  # (Python 3.12 freezes a few hundred of its own at start-up)
    tracked = len(gc.get_objects())
    thresholds = gc.get_threshold()
    with run_heap():
        assert gc.get_threshold() == (max(thresholds[0], RUN_YOUNG_THRESHOLD), *thresholds[1:])
        frozen = gc.get_freeze_count()
        assert frozen >= interpreters + tracked and len(gc.get_objects()) < 100  # (only the run's are walked)
        made = Cycle()
        del made
        assert gc.collect() >= 1  # (the run's own garbage, a cycle, is collected)
        assert gc.get_freeze_count() == frozen
    assert gc.get_freeze_count() == 0 and gc.get_threshold() == thresholds
    assert any(obj is before for obj in gc.get_objects())  # (tracked again)
