"""Session-wide test environment for friction_sim.

This module is imported by pytest before any test module, and therefore before
rclpy is imported anywhere.  The RMW layer reads its discovery settings from
the environment when rclpy initialises, so they must be set here:

* ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` (always forced in tests): DDS
  discovery never leaves this machine.
* ``ROS_DOMAIN_ID``: a random domain per test session, so concurrent test runs
  (or a demo running beside them) do not see each other's nodes and topics.
  If the Makefile (or the caller) already chose one, that value is kept; each
  pytest-xdist worker moves it by half the range (two workers: two domains).
* ``MPLBACKEND=Agg``: plotting works without a display (CI has none).
"""

import os
import random
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import settings

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('ROS_DOMAIN_ID', str(random.SystemRandom().randint(1, 100)))
# Under pytest-xdist (`make test` runs two workers) each worker is a session of its own:
# a domain of its own too (the session's, moved by half the range per worker), so two
# tests that use the same names (the README's commands use the root namespace) never meet.
_WORKER = os.environ.get('PYTEST_XDIST_WORKER', '')
if _WORKER.startswith('gw') and _WORKER[2:].isdigit():
    os.environ['ROS_DOMAIN_ID'] = str((int(os.environ['ROS_DOMAIN_ID']) - 1 + 50 * int(_WORKER[2:])) % 100 + 1)
os.environ['MPLBACKEND'] = 'Agg'

# CI runs the property tests on a fixed set of examples (reproducible runs);
# on a developer's machine hypothesis explores new ones every time.
settings.register_profile('ci', derandomize=True, database=None)
if os.environ.get('CI'):
    settings.load_profile('ci')


@pytest.fixture(scope='module')
def ros() -> Iterator[None]:
    """rclpy initialised for the tests of one module (imported here, after the
    environment above is set)."""
    import rclpy

    rclpy.init()
    yield
    rclpy.try_shutdown()


@pytest.fixture
def failing_core(monkeypatch: pytest.MonkeyPatch) -> None:
    """The core takes drive_force ``helpers.POISON`` half-way, then raises."""
    from helpers import fail_on_poison

    fail_on_poison(monkeypatch)


@pytest.fixture(scope='module')
def real_recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """2 s at 1 kHz with random commands, external forces, a refused command
    and a plant change (the recording tests of test/io and test/experiment)."""
    import numpy as np

    from friction_sim.core.model.commands import Command
    from friction_sim.core.runtime.simulation import random_schedule
    from friction_sim.experiment.offline import record_offline

    path = tmp_path_factory.mktemp('rec') / 'run.mcap'
    schedule = random_schedule(np.random.default_rng(21), 2.0, external=True)
    schedule += [Command(0.7, 'excitation_amplitude', {'excitation_amplitude': -4.0}),  # refused: Pa < 0
                 Command(1.1, 'parameters', {'mass': 1.3})]
    record_offline(path, schedule=schedule, duration=2.0)
    return path
