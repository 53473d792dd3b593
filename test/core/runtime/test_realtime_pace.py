"""The real-time loop when asked for more than the machine computes
(core/realtime.py): one advance takes at most MAX_SAMPLES_PER_ADVANCE log
samples, and the simulation then falls behind the wall clock, continuously
and exactly, instead of one tick holding the node for seconds."""

from __future__ import annotations

from friction_sim.core.engine.single import Slider
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.runtime.realtime import MAX_SAMPLES_PER_ADVANCE, NS_PER_S, RealtimeSlider


def test_an_advance_takes_at_most_its_share_of_samples_and_time_falls_behind() -> None:
    rt = RealtimeSlider(SliderParams(), Inputs(excitation_frequency=10.0), wall_ns=0, real_time_factor=1000.0,
                        log_rate=1000.0)
    wall = 0
    times: list[float] = []
    for _ in range(5):
        wall += NS_PER_S // 10  # 0.1 s of wall time asks for 100 s = 100,000 samples
        tick = rt.tick(wall)
        assert len(tick.samples) <= MAX_SAMPLES_PER_ADVANCE + 1
        times.extend(s.t for s in tick.samples)
    assert rt.behind == 5
    assert rt.slider.t == rt.now(wall), "simulation time is held where the advance stopped"
    # one unbroken 1 kHz grid from the start, no jump anywhere
    assert times == [k / 1000.0 for k in range(len(times))]
    report = rt.diagnostics(wall)
    assert report["ticks_behind_in_interval"] == 5 and report["achieved_real_time_factor"] < 20.0


def test_falling_behind_does_not_change_the_motion() -> None:
    """The states logged by a slider that fell behind are the exact motion."""
    inputs = Inputs(excitation_frequency=20.0)
    rt = RealtimeSlider(SliderParams(), inputs, wall_ns=0, real_time_factor=1000.0, log_rate=1000.0)
    samples = []
    for k in range(1, 4):
        samples.extend(rt.tick(k * NS_PER_S // 10).samples)
    assert rt.behind == 3
    reference = Slider(SliderParams(), inputs)
    for state in samples:
        reference.advance_to(state.t)
        assert reference.state() == state


def test_within_its_share_the_clock_is_followed_exactly() -> None:
    rt = RealtimeSlider(SliderParams(), Inputs(), wall_ns=0, real_time_factor=2.0, log_rate=1000.0)
    rt.tick(NS_PER_S // 10)
    assert rt.behind == 0 and rt.slider.t == 0.2
