"""Fixtures shared by the recording tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from friction_sim.core.model.commands import Command
from friction_sim.core.runtime.simulation import random_schedule
from friction_sim.io.offline import record_offline


@pytest.fixture(scope="module")
def real_recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """2 s at 1 kHz with random commands, external forces, a refused command
    and a plant change."""
    path = tmp_path_factory.mktemp("rec") / "run.mcap"
    schedule = random_schedule(np.random.default_rng(21), 2.0, external=True)
    schedule += [Command(0.7, "excitation_amplitude", {"excitation_amplitude": -4.0}),  # refused: Pa < 0
                 Command(1.1, "parameters", {"mass": 1.3})]
    record_offline(path, schedule=schedule, duration=2.0)
    return path
