"""The log grid's points, a segment at a time, are where advancing point by point puts them."""

from __future__ import annotations

import math

from friction_sim.core.engine.single import Slider
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.runtime.accelerometer import Accelerometer
from friction_sim.core.runtime.loggrid import LogGrid

RATE = 1000.0


def test_a_point_the_rounded_grid_puts_just_before_the_slider_is_read_where_the_slider_stands() -> None:
    """The grid takes a point k with k/rate a hair (rounding) before where the slider already
    stands; it is logged and read at the slider's time, in the segment the slider is in, as
    advancing to it (to no earlier than where it stands) and reading there gives."""
    here = math.nextafter(5 / RATE, 1.0)  # (an input change landed one ulp after the grid point)
    slider, reference = (Slider(SliderParams(actuator="resonant"), Inputs(drive_level=0.4)) for _ in range(2))
    grid = LogGrid(RATE, Accelerometer(RATE))
    grid.advance(slider, 4 / RATE)  # (the points up to 4 are logged)
    grid.take()
    for each in (slider, reference):
        each.advance_to(here)
        each.set_inputs(drive_level=0.9)
    grid.advance(slider, 8 / RATE)
    _, samples, readings = grid.take()
    assert [sample.t for sample in samples] == [reading.t for reading in readings] == [here, 6e-3, 7e-3, 8e-3]
    expected = []
    for when in (here, 6e-3, 7e-3, 8e-3):
        reference.advance_to(when)
        expected.append(reference.state())
    assert list(samples) == expected
