"""What the slider node says about itself (friction_sim.ros.slider_outputs), without a node."""

from __future__ import annotations

import math
import threading
from typing import Any

from friction_sim.core.meanspeed.predict import predict
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.runtime.realtime import RealtimeSlider
from friction_sim.ros.slider_outputs import PREDICTION_TRIES, consistent_report


class ChangingWhilePredicting(RealtimeSlider):
    """A runtime whose drive force a command changes while the first ``changes`` predictions are made
    (as the tick thread does while the diagnostics' prediction simulates outside the lock)."""

    def __init__(self, changes: int) -> None:
        super().__init__(SliderParams(), Inputs(), wall_ns=0)
        self.changes, self.made = changes, 0

    def prediction(self, params: Any = None, inputs: Any = None) -> Any:
        made = super().prediction(params, inputs)
        self.made += 1
        if self.made <= self.changes:
            self.slider.set_inputs(self.slider.inputs.replace(drive_force=self.slider.inputs.drive_force + 0.01))
        return made


def test_a_report_pairs_the_plant_it_shows_with_that_plants_prediction() -> None:
    rt = ChangingWhilePredicting(changes=PREDICTION_TRIES - 1)
    report = consistent_report(rt, threading.Lock(), lambda: 0)
    assert report["drive_force"] == rt.slider.inputs.drive_force
    assert report["predicted_U"] == predict(rt.slider.params, rt.slider.inputs).u
    assert rt.made == PREDICTION_TRIES


def test_a_plant_that_changes_at_every_try_is_reported_without_a_prediction() -> None:
    rt = ChangingWhilePredicting(changes=PREDICTION_TRIES)
    report = consistent_report(rt, threading.Lock(), lambda: 0)
    assert report["drive_force"] == rt.slider.inputs.drive_force
    assert math.isnan(report["predicted_U"]) and math.isnan(report["phi"])
    assert rt.made == PREDICTION_TRIES
