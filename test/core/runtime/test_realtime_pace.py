"""The real-time loop when asked for more than the machine computes
(core/realtime.py): one advance takes at most MAX_SAMPLES_PER_ADVANCE log
samples, and the simulation then falls behind the wall clock, continuously
and exactly, instead of one tick holding the node for seconds."""

from __future__ import annotations

from friction_sim.core.engine.single import Slider
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.runtime.loggrid import MAX_SAMPLES_PER_ADVANCE
from friction_sim.core.runtime.realtime import NS_PER_S, RealtimeSlider


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
    assert rt.pace.behind == 5
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
    assert rt.pace.behind == 3
    reference = Slider(SliderParams(), inputs)
    for state in samples:
        reference.advance_to(state.t)
        assert reference.state() == state


def test_within_its_share_the_clock_is_followed_exactly() -> None:
    rt = RealtimeSlider(SliderParams(), Inputs(), wall_ns=0, real_time_factor=2.0, log_rate=1000.0)
    rt.tick(NS_PER_S // 10)
    assert rt.pace.behind == 0 and rt.slider.t == 0.2


MS = NS_PER_S // 1000


def _ticking(rt: RealtimeSlider, wall: int, ticks: int, step: int = MS) -> int:
    """``ticks`` ticks ``step`` ns apart from ``wall``; returns the wall time of the last."""
    for _ in range(ticks):
        wall += step
        rt.tick(wall)
    return wall


def test_a_stall_of_the_host_is_simulated_only_up_to_max_catch_up() -> None:
    """A tick 0.5 s late (a garbage collection) simulates max_catch_up of it
    (times the real-time factor): the rest slips, counted, and the clock is
    followed exactly again from there."""
    rt = RealtimeSlider(SliderParams(), Inputs(), wall_ns=0, real_time_factor=0.5, max_catch_up=0.02)
    wall = _ticking(rt, 0, 10)
    assert rt.slider.t == 0.005 and rt.pace.stalls == 0
    readings = [rt.now(wall + k * MS) for k in range(0, 500, 7)]
    assert readings == sorted(readings) and readings[-1] == 0.005 + 0.5 * 0.02, \
        "readings during the stall run up to the catch-up limit and stand there"
    wall += 500 * MS
    rt.tick(wall)
    assert rt.slider.t == 0.005 + 0.5 * 0.02, "the late tick simulates 20 ms of wall time at half speed"
    assert rt.now(wall) == rt.slider.t and rt.diagnostics(wall)["sim_time"] == rt.slider.t, "no step back"
    assert rt.pace.stalls == 1 and rt.pace.time_slipped == 0.5 * 0.48
    _ticking(rt, wall, 4)
    assert rt.slider.t == 0.015 + 0.5 * 0.004 and rt.pace.stalls == 1
    report = rt.diagnostics(wall + 4 * MS)
    assert report["sim_time"] == rt.slider.t
    assert (report["stalls"], report["time_slipped"], report["max_catch_up"]) == (1, 0.24, 0.02)


def test_a_late_tick_within_max_catch_up_catches_up_in_full() -> None:
    rt = RealtimeSlider(SliderParams(), Inputs(), wall_ns=0, max_catch_up=0.02)
    rt.tick(20 * MS)
    assert rt.slider.t == 0.02 and rt.pace.stalls == 0


def test_max_catch_up_is_never_less_than_two_ticks() -> None:
    """At publish_rate 10 Hz ticks are 100 ms apart: on time, they never slip."""
    rt = RealtimeSlider(SliderParams(), Inputs(), wall_ns=0, publish_rate=10.0, max_catch_up=0.02)
    wall = _ticking(rt, 0, 5, 100 * MS)
    assert rt.slider.t == 0.5 and rt.pace.stalls == 0
    rt.tick(wall + 250 * MS)
    assert rt.slider.t == 0.7 and rt.pace.stalls == 1


def test_a_pause_is_not_a_stall() -> None:
    rt = RealtimeSlider(SliderParams(), Inputs(), wall_ns=0, max_catch_up=0.02)
    rt.tick(MS)
    rt.pause(MS)
    rt.tick(5 * NS_PER_S)
    rt.resume(5 * NS_PER_S)
    rt.tick(5 * NS_PER_S + MS)
    assert rt.slider.t == 0.002 and rt.pace.stalls == 0


def test_max_catch_up_is_a_setting_checked_at_the_edge() -> None:
    rt = RealtimeSlider(SliderParams(), Inputs(), wall_ns=0, max_catch_up=0.02)
    assert rt.configure({"max_catch_up": 0.5}, MS).accepted and rt.pace.max_catch_up == 0.5
    refused = rt.configure({"max_catch_up": 0.0}, 2 * MS)
    assert not refused.accepted and "max_catch_up" in refused.reason and "0.0" in refused.reason
    assert rt.pace.max_catch_up == 0.5
    rt.tick(2 * MS + 400 * MS)
    assert rt.pace.stalls == 0, "within the new limit"


def test_a_stall_does_not_change_the_motion() -> None:
    """The states a slider logs across a slip are the exact motion: only the
    mapping of wall time to simulation time moved."""
    inputs = Inputs(excitation_frequency=20.0)
    rt = RealtimeSlider(SliderParams(), inputs, wall_ns=0, log_rate=1000.0, max_catch_up=0.02)
    samples = []
    wall = 0
    for gap in (MS, 300 * MS, MS, 700 * MS, 5 * MS):
        wall += gap
        samples.extend(rt.tick(wall).samples)
    assert rt.pace.stalls == 2
    assert [s.t for s in samples] == [k / 1000.0 for k in range(len(samples))], "one unbroken log grid"
    reference = Slider(SliderParams(), inputs)
    for state in samples:
        reference.advance_to(state.t)
        assert reference.state() == state


def test_a_hold_for_a_wait_the_ticks_simulated_since_never_puts_the_clock_behind_the_slider() -> None:
    """A parameter set that waited 30 ms for the recorder held the tick thread, which then
    simulated those 30 ms; holding the clock for them afterwards must not make it read a
    time before states already made (diagnostics report it as sim_time)."""
    rt = RealtimeSlider(SliderParams(), Inputs(), wall_ns=0, log_rate=1000.0)
    rt.tick(100_000_000)  # 0.1 s
    rt.tick(130_000_000)  # the 30 ms the set waited, simulated after it
    rt.hold(30_000_000, 130_000_000)
    assert rt.clock.now_ns(130_000_000) == round(rt.slider.t * NS_PER_S) == 130_000_000
    assert rt.diagnostics(130_000_000)["sim_time"] >= rt.slider.t
    assert rt.clock.now_ns(140_000_000) == 140_000_000, "and it runs on at its rate"


def test_a_hold_for_a_wait_of_the_ticks_themselves_stops_simulation_time_for_it() -> None:
    rt = RealtimeSlider(SliderParams(), Inputs(), wall_ns=0, log_rate=1000.0)
    rt.tick(100_000_000)
    rt.hold(30_000_000, 140_000_000)  # the tick thread itself waited 30 of the last 40 ms
    assert rt.clock.now_ns(140_000_000) == 110_000_000
