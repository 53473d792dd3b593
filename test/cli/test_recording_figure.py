"""``friction-sim replay --plot`` on a recording of a hopping slider: the
height above the track gets its own panel, with the recorded extremes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from friction_sim.cli.recording_figure import plot
from friction_sim.core.model.commands import Command
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.experiment.offline import record_offline
from friction_sim.io.reader import read_recording
from friction_sim.io.series import POSITION_XZ, state_values


@pytest.mark.parametrize(("amplitude", "panels"), [(15.0, 5), (5.0, 4)])  # Gamma = 1.5 hops; a = 0.5 does not
def test_a_flight_recording_gets_a_height_panel(tmp_path: Path, amplitude: float, panels: int) -> None:
    path = tmp_path / "run.mcap"
    schedule = [Command(0.1, "excitation_amplitude", {"excitation_amplitude": amplitude * 1.2})]
    record_offline(path, SliderParams(), Inputs(excitation_amplitude=amplitude), schedule, duration=0.2,
                   log_rate=2000.0)
    recording = read_recording(path)
    figure = plot(recording)
    assert len(figure.axes) == panels
    _, pose = state_values(recording, recording.messages_on("pose"), POSITION_XZ)
    if panels == 4:
        assert np.all(pose[:, 2] == 0.0)
        return
    height = figure.axes[4]
    assert height.get_ylabel() == "height z [µm]" and figure.axes[-1].get_xlabel() == "simulation time t [s]"
    drawn = height.lines[0].get_ydata()
    assert pose[:, 2].max() > 0.0
    assert np.max(drawn) == pytest.approx(pose[:, 2].max() * 1e6, rel=1e-12), "the thinned trace keeps the top"
    assert len(height.lines) == 1 + 1, "the z trace and the one command's line"
