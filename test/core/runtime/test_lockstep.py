"""Lockstep without ROS: the gate's bookkeeping, and the slider it advances.

:class:`LockstepGate` decides how far the slider may go (the oldest unanswered
sample plus the actuation delay, the scheduler's promise, a pause or a step);
:class:`LockstepSlider` goes exactly that far.  The point of lockstep is that a
closed loop depends on nothing but the messages: so the closed-loop tests here
drive the slider with a fake controller in a plain loop and check that *when*
the answers arrive (at once, or after the slider has stood waiting for a few
iterations, with any wall clock) changes nothing, bit for bit.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from friction_sim.core.model.commands import Command, Outcome
from friction_sim.core.model.events import SliderState
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.model.records import PeriodSummary
from friction_sim.core.model.spec import NS_PER_S
from friction_sim.core.runtime.lockstep import (
    CONTROLLER,
    SCHEDULER,
    UNBOUNDED,
    LockstepGate,
    LockstepSlider,
    participants,
    to_ns,
)
from friction_sim.errors import ParameterError

MS = 1_000_000
PA = "excitation_amplitude"
U = "drive_level"
#: The resonant plant of the brief, driven through its drive level.
RESONANT = SliderParams(actuator="resonant", natural_frequency=52.0, full_drive_acceleration=20.0)


def pa_law(v: float) -> float:
    """A deterministic controller of the default plant: Pa from the measured mean velocity."""
    return min(max(5.0 + 1e4 * (1e-4 - v), 0.0), 9.0)


def u_law(v: float) -> float:
    """A deterministic controller of the resonant plant: the drive level from the mean velocity."""
    return min(max(0.6 + 1e3 * (1e-3 - v), 0.0), 1.0)


def _gate(delay: float, *who: str) -> LockstepGate:
    return LockstepGate(frozenset(who), delay, 10.0)


def _slider(params: SliderParams, inputs: Inputs, gate: LockstepGate) -> LockstepSlider:
    return LockstepSlider(params, inputs, wall_ns=0, gate=gate, publish_rate=1000.0, mean_window_periods=1,
                          log_rate=None)


def _pa(t: float, value: float) -> Command:
    return Command(t, PA, {PA: value})


# -- the gate --------------------------------------------------------------------------


def test_the_limit_is_the_oldest_unanswered_sample_plus_the_delay_until_its_answer_is_due() -> None:
    """With the controller taking part, a published sample at t_k bounds the slider at
    t_k + d until it is answered; the answer is then due exactly at t_k + d (so the
    limit stays there until it is taken), and then the next awaited sample bounds it."""
    gate = _gate(0.005, CONTROLLER)
    assert gate.delay_ns == 5 * MS
    assert gate.limit_ns() == UNBOUNDED
    gate.sample(20 * MS)
    assert gate.limit_ns() == 25 * MS
    gate.sample(40 * MS)
    assert gate.limit_ns() == 25 * MS, "the oldest awaited sample bounds"
    assert gate.blocker(24 * MS) == ("", False)
    assert gate.blocker(25 * MS) == ("the controller: no answer on control_answer to the mean_velocity sample of "
                                     "t = 0.020000000 s", False), "named, and not yet joined (it never answered)"
    command = _pa(0.02, 3.0)
    assert gate.answer(20 * MS, [command]) is True
    assert list(gate.awaited) == [40 * MS] and gate.answers == 1 and gate.stale_answers == 0
    assert gate.limit_ns() == 25 * MS, "the answer is due at the stamp plus the delay"
    assert gate.blocker(25 * MS) == ("", False)
    assert gate.due(25 * MS - 1) == []
    assert gate.due(25 * MS) == [command]
    assert gate.due(25 * MS) == [], "taken off the queue"
    assert gate.limit_ns() == 45 * MS
    assert gate.blocker(45 * MS) == ("the controller: no answer on control_answer to the mean_velocity sample of "
                                     "t = 0.040000000 s", True), "it has answered before: it has joined"


def test_a_zero_delay_holds_the_slider_at_the_sample_itself() -> None:
    gate = _gate(0.0, CONTROLLER)
    gate.sample(20 * MS)
    assert gate.limit_ns() == 20 * MS
    assert gate.blocker(20 * MS)[0].startswith("the controller:")
    assert gate.blocker(20 * MS - 1) == ("", False)


def test_an_answer_to_a_sample_not_awaited_is_stale_and_changes_nothing() -> None:
    """A stamp never published, or one answered already (the controller answers
    a sample published again), is counted and changes neither the awaited
    samples, nor the queue, nor the limit."""
    gate = _gate(0.005, CONTROLLER)
    gate.sample(20 * MS)
    assert gate.answer(20 * MS, [_pa(0.02, 3.0)])
    gate.sample(40 * MS)
    before = (list(gate.awaited), gate.limit_ns(), gate.answers)
    assert gate.answer(30 * MS, [_pa(0.03, 7.0)]) is False  # never published
    assert gate.answer(20 * MS, [_pa(0.02, 8.0)]) is False  # a repeat
    assert gate.stale_answers == 2
    assert (list(gate.awaited), gate.limit_ns(), gate.answers) == before
    assert gate.due(UNBOUNDED) == [_pa(0.02, 3.0)], "only the first answer is queued"


def test_an_answer_to_a_later_sample_settles_the_earlier_ones() -> None:
    """Answers come in order: one to a later sample means the earlier ones are past."""
    gate = _gate(0.005, CONTROLLER)
    for stamp in (20 * MS, 40 * MS, 60 * MS):
        gate.sample(stamp)
    assert gate.answer(40 * MS, [])
    assert list(gate.awaited) == [60 * MS]
    assert gate.answer(20 * MS, []) is False and gate.stale_answers == 1
    assert gate.limit_ns() == 65 * MS, "an empty answer queues nothing"


def test_a_gate_without_the_controller_awaits_no_sample() -> None:
    gate = _gate(0.005, SCHEDULER)
    gate.sample(20 * MS)
    assert not gate.awaited
    assert gate.limit_ns() == 0, "only the scheduler's (absent) promise bounds"
    assert gate.answer(20 * MS, [_pa(0.02, 3.0)]) is False and gate.stale_answers == 1


def test_answers_act_before_scheduled_commands_at_the_same_time() -> None:
    """Due at one time: the controller's answers first, then the scheduler's
    commands, each group in arrival order, whatever order they were queued in."""
    gate = _gate(0.005, CONTROLLER, SCHEDULER)
    scheduled = [_pa(0.025, 2.0), Command(0.025, "drive_force", {"drive_force": 0.5})]
    assert gate.promise(25 * MS, scheduled, 0) == ""
    assert gate.promise(25 * MS, [_pa(0.025, 1.0)], 0) == "", "a promise may repeat its stamp"
    gate.sample(20 * MS)
    answer = [_pa(0.02, 7.0), Command(0.02, "excitation_frequency", {"excitation_frequency": 51.0})]
    assert gate.answer(20 * MS, answer)
    assert gate.due(25 * MS) == [*answer, *scheduled, _pa(0.025, 1.0)]


def test_on_the_slider_the_scheduled_command_at_the_answer_time_has_the_last_word() -> None:
    """The same ordering seen on the plant: Pa from the answer, then the
    scheduler's Pa at the same instant, which stays in force."""
    gate = _gate(0.005, CONTROLLER, SCHEDULER)
    rt = _slider(SliderParams(), Inputs(), gate)
    assert gate.promise(25 * MS, [_pa(0.025, 2.0)], rt.t_ns) == ""
    outcomes: list[Outcome] = []
    for _ in range(20):
        outcomes += rt.due_commands(0)
        tick = rt.advance(0)
        for period in tick.periods if tick is not None else []:
            assert gate.answer(to_ns(period.t), [_pa(period.t, 7.0)])
    assert [(o.t, o.values[PA], o.accepted) for o in outcomes] == [(0.025, 7.0, True), (0.025, 2.0, True)]
    assert rt.slider.inputs.excitation_amplitude == 2.0
    assert rt.t_ns == 25 * MS, "the promise holds it there"


# -- the scheduler ----------------------------------------------------------------------


def test_the_scheduler_promise_bounds_the_slider() -> None:
    """Before the scheduler speaks the slider stands at 0; then it goes up to
    each promise, never past it, and a command stamped there acts exactly there."""
    gate = _gate(0.0, SCHEDULER)
    rt = _slider(SliderParams(), Inputs(), gate)
    assert rt.advance(0) is None
    assert gate.blocker(rt.t_ns) == ("the scheduler: no stamped_command yet", False)
    assert gate.promise(30 * MS, [], rt.t_ns) == ""
    times = _run_until_blocked(rt)
    assert max(times) == rt.t_ns == 30 * MS
    assert gate.blocker(rt.t_ns) == ("the scheduler: no stamped_command past t = 0.030000000 s", True)
    assert gate.promise(50 * MS, [_pa(0.05, 3.0)], rt.t_ns) == ""
    outcomes = rt.due_commands(0)
    assert outcomes == [], "not due yet"
    times = _run_until_blocked(rt)
    assert max(times) == rt.t_ns == 50 * MS
    outcomes = rt.due_commands(0)
    assert [(o.t, o.values[PA], o.accepted) for o in outcomes] == [(0.05, 3.0, True)]
    assert rt.slider.inputs.excitation_amplitude == 3.0
    assert rt.advance(0) is None, "the promise (50 ms) still holds it"


def test_a_window_ending_at_the_promise_is_reported_once_the_promise_moves_on() -> None:
    """What the scheduler does at a time comes before the controller is asked
    about it: the period ending exactly at the promise is held back."""
    gate = _gate(0.0, SCHEDULER)
    rt = _slider(SliderParams(), Inputs(), gate)
    assert gate.promise(40 * MS, [], rt.t_ns) == ""
    reported = [p.t for _ in range(10) if (tick := rt.advance(0)) is not None for p in tick.periods]
    assert rt.t_ns == 40 * MS
    assert reported == [0.02], "the period ending at 40 ms waits"
    assert gate.promise(41 * MS, [], rt.t_ns) == ""
    tick = rt.advance(0)
    assert tick is not None
    assert [p.t for p in tick.periods] == [0.04]
    assert tick.state.t == 0.04, "reported first, before the slider moves on"


def test_a_stamped_command_before_the_last_promise_is_refused_naming_stamp_value_and_limit() -> None:
    gate = _gate(0.0, SCHEDULER)
    assert gate.promise(30 * MS, [], 0) == ""
    state = (gate.promise_ns, gate.scheduled, gate.limit_ns())
    why = gate.promise(20 * MS, [_pa(0.02, 3.0)], 0)
    assert why == ("stamped_command: header.stamp = 0.02 s rejected: must be >= 0.03 s "
                   "(the slider's time and the scheduler's last promise)")
    assert (gate.promise_ns, gate.scheduled, gate.limit_ns()) == state, "a refusal changes nothing"
    assert gate.due(UNBOUNDED) == []
    assert gate.promise(30 * MS, [_pa(0.03, 3.0)], 0) == "", "at the promise itself: accepted"


def test_a_stamped_command_before_the_slider_time_is_refused() -> None:
    """Without the scheduler taking part, stamped commands still may not reach into the past."""
    gate = _gate(0.0)
    rt = _slider(SliderParams(), Inputs(), gate)
    while rt.t_ns < 20 * MS:
        assert rt.advance(0) is not None
    assert rt.t_ns == 20 * MS
    why = gate.promise(20 * MS - 1, [_pa(0.02, 3.0)], rt.t_ns)
    assert why == ("stamped_command: header.stamp = 0.019999999 s rejected: must be >= 0.02 s "
                   "(the slider's time and the scheduler's last promise)")
    assert gate.scheduled == 0 and gate.due(UNBOUNDED) == []
    assert gate.promise(20 * MS, [_pa(0.02, 3.0)], rt.t_ns) == ""
    assert gate.promise_ns == UNBOUNDED, "no scheduler: nothing promised, nothing bounds"
    outcomes = rt.due_commands(0)
    assert [(o.t, o.values[PA], o.accepted) for o in outcomes] == [(0.02, 3.0, True)]


# -- pause, step, resume ----------------------------------------------------------------


def _run_until_blocked(rt: LockstepSlider, limit: int = 1000) -> list[int]:
    """Advance until the gate stops the slider; the times [ns] it stood at."""
    times: list[int] = []
    for _ in range(limit):
        if rt.advance(0) is None:
            return times
        times.append(rt.t_ns)
    raise AssertionError(f"not blocked after {limit} advances")


def test_pause_holds_step_moves_the_hold_and_resume_releases() -> None:
    gate = _gate(0.0)  # nobody to wait for: only the hold bounds the slider
    rt = _slider(SliderParams(), Inputs(), gate)
    while rt.t_ns < 20 * MS:
        rt.advance(0)
    assert rt.t_ns == 20 * MS
    refused = rt.step(0.005, 0)
    assert refused.reason == "step: the simulation is running; call pause first"
    assert rt.resume(0).reason == "resume: not paused"
    assert rt.pause(0).accepted and rt.paused
    assert rt.pause(0).reason == "pause: already paused at t = 0.020000000 s"
    assert [rt.advance(0) for _ in range(3)] == [None, None, None]
    assert rt.t_ns == 20 * MS
    assert gate.blocker(rt.t_ns) == ("", False), "a pause waits for no participant"

    assert rt.step(0.005, 0).accepted
    assert not rt.paused, "a step under way is not a pause"
    assert _run_until_blocked(rt) == [25 * MS]
    assert rt.paused, "at its end the step is a pause again"

    assert rt.step(0.01, 0).accepted and rt.step(0.01, 0).accepted  # two steps extend the hold
    assert gate.hold_ns == 45 * MS
    assert _run_until_blocked(rt) == [40 * MS, 45 * MS]
    assert rt.paused and rt.t_ns == 45 * MS

    for bad in (0.0, 1e-10, -0.01, math.nan, math.inf):
        outcome = rt.step(bad, 0)
        assert outcome.reason == f"step: duration = {bad!r} s rejected: must be >= 1 ns"
    assert rt.t_ns == 45 * MS and gate.hold_ns == 45 * MS

    assert rt.resume(0).accepted and not rt.paused and not gate.held
    tick = rt.advance(0)
    assert tick is not None and not tick.paused
    assert rt.t_ns == 60 * MS, "running: to the next period's end"


def test_a_pause_during_a_step_cuts_it_short() -> None:
    gate = _gate(0.0)
    rt = _slider(SliderParams(), Inputs(), gate)
    assert rt.pause(0).accepted
    assert rt.step(0.03, 0).accepted
    assert rt.advance(0) is not None and rt.t_ns == 0
    assert rt.advance(0) is not None and rt.t_ns == 20 * MS
    assert rt.pause(0).accepted, "a step under way is not a pause: pausing is allowed"
    assert rt.advance(0) is None and rt.t_ns == 20 * MS


def test_a_window_ending_at_a_step_end_is_reported_when_the_next_step_moves_on() -> None:
    gate = _gate(0.0)
    rt = _slider(SliderParams(), Inputs(), gate)
    assert rt.pause(0).accepted and rt.step(0.04, 0).accepted
    periods = [p.t for _ in range(10) if (tick := rt.advance(0)) is not None for p in tick.periods]
    assert rt.t_ns == 40 * MS and periods == [0.02]
    assert rt.step(0.001, 0).accepted
    tick = rt.advance(0)
    assert tick is not None and [p.t for p in tick.periods] == [0.04] and tick.state.t == 0.04
    assert _run_until_blocked(rt) == [41 * MS]


# -- the closed loop ---------------------------------------------------------------------


@dataclass
class Loop:
    """What one closed-loop run made."""

    state: SliderState
    periods: list[PeriodSummary]
    outcomes: list[Outcome]
    #: Advances that returned None (the slider stood waiting), and those where it stood
    #: exactly at an unanswered sample plus the delay.
    blocked: int
    at_bound: int
    gate: LockstepGate
    #: The inputs in force at the end.
    inputs: Inputs


def closed_loop(params: SliderParams, inputs: Inputs, field: str, law: Callable[[float], float], delay: float, *,
                lateness: Sequence[int] | None = None, wall_step: int = 0, until: float = 0.3,
                controls: Mapping[int, tuple[str, float]] | None = None) -> Loop:
    """Run the slider with a fake controller answering each sample with ``field`` =
    ``law(mean velocity)``, until simulation time ``until``.

    ``lateness`` None: each sample is answered as soon as the advance that made it
    returns.  Else answers come only while the slider stands waiting, the i-th
    after ``lateness[i % len]`` further advances that return None (no-op iterations).
    ``wall_step``: the wall time [ns] passing per iteration.  ``controls``:
    iteration -> ('pause' | 'step' | 'resume', step length [s]) done before the advance.
    Checks on the way that the slider never passes an unanswered sample plus the delay.
    """
    gate = _gate(delay, CONTROLLER)
    rt = _slider(params, inputs, gate)
    periods: list[PeriodSummary] = []
    outcomes: list[Outcome] = []
    pending: deque[PeriodSummary] = deque()
    blocked = at_bound = idle = answered = wall = 0

    def answer(period: PeriodSummary) -> None:
        assert gate.answer(to_ns(period.t), [Command(period.t, field, {field: law(period.mean_velocity)})])

    for iteration in range(100_000):
        if rt.slider.t >= until:
            break
        wall += wall_step
        action, length = (controls or {}).get(iteration, ("", 0.0))
        if action:
            outcome = rt.pause(wall) if action == "pause" else rt.resume(wall) if action == "resume" \
                else rt.step(length, wall)
            assert outcome.accepted, outcome.reason
        outcomes += rt.due_commands(wall)
        bound = gate.awaited[0] + gate.delay_ns if gate.awaited else UNBOUNDED
        tick = rt.advance(wall)
        assert rt.t_ns <= bound, "the slider passed an unanswered sample plus the delay"
        if gate.awaited:
            assert rt.t_ns <= gate.awaited[0] + gate.delay_ns
            at_bound += rt.t_ns == gate.awaited[0] + gate.delay_ns
        if tick is not None:
            periods += tick.periods
            pending += tick.periods
            if lateness is None:
                while pending:
                    answer(pending.popleft())
            continue
        blocked += 1
        if lateness is not None and pending:
            if idle >= lateness[answered % len(lateness)]:
                answer(pending.popleft())
                idle, answered = 0, answered + 1
            else:
                idle += 1
        else:
            assert gate.held, "standing still with no answer to give and no hold: a deadlock"
    else:
        raise AssertionError("the loop did not reach its end")
    return Loop(rt.slider.state(), periods, outcomes, blocked, at_bound, gate, rt.slider.inputs)


def _check_answers_act_at_stamp_plus_delay(run: Loop, field: str, law: Callable[[float], float]) -> None:
    """Every command is accepted, is the answer to one sample, in order, and acts at its stamp plus the delay."""
    assert all(o.accepted for o in run.outcomes), [o.reason for o in run.outcomes if not o.accepted]
    assert [o.name for o in run.outcomes] == [field] * len(run.outcomes)
    late = math.ceil(run.gate.delay_ns / (20 * MS)) + 1  # samples whose answer is not due by the end
    assert len(run.periods) - late <= len(run.outcomes) <= len(run.periods)
    for outcome, period in zip(run.outcomes, run.periods):
        assert to_ns(outcome.t) == to_ns(period.t) + run.gate.delay_ns
        assert outcome.values == {field: law(period.mean_velocity)}


def _record(run: Loop) -> tuple[SliderState, list[PeriodSummary], list[tuple[float, dict[str, float]]]]:
    """The final state, every period's summary and every command (time and values): what must not change."""
    return run.state, run.periods, [(o.t, dict(o.values)) for o in run.outcomes]


CASES = {
    "force": (SliderParams(), Inputs(), PA, pa_law),
    "resonant": (RESONANT, Inputs(drive_level=0.6), U, u_law),
}


@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("delay", [0.0, 0.005, 0.02, 0.033])
def test_every_answer_acts_exactly_at_its_sample_plus_the_actuation_delay(case: str, delay: float) -> None:
    params, inputs, field, law = CASES[case]
    run = closed_loop(params, inputs, field, law, delay, until=0.5)
    _check_answers_act_at_stamp_plus_delay(run, field, law)
    assert len(run.periods) == 25 and [p.n for p in run.periods] == list(range(1, 26))
    assert len({o.values[field] for o in run.outcomes}) > 5, "the controller does act (else nothing is tested)"
    assert run.gate.answers == len(run.periods) and run.gate.stale_answers == 0
    assert getattr(run.inputs, field) == run.outcomes[-1].values[field], "the last answer applied is in force"


def test_an_answer_at_a_time_off_the_period_grid_acts_at_that_exact_float() -> None:
    """The command time is the stamp plus the delay as a float, not only to the nanosecond."""
    run = closed_loop(SliderParams(), Inputs(), PA, pa_law, 0.005)
    assert run.outcomes and [o.t for o in run.outcomes] == [
        (to_ns(p.t) + 5 * MS) / NS_PER_S for p in run.periods[:len(run.outcomes)]]


@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("delay", [0.0, 0.005, 0.02, 0.033])
def test_when_the_answers_arrive_changes_nothing(case: str, delay: float) -> None:
    """The same closed loop answered at once, and answered only after the slider has
    stood waiting for a few no-op iterations (with the wall clock running): the
    final state, every period's mean and every command are equal bit for bit."""
    params, inputs, field, law = CASES[case]
    prompt = closed_loop(params, inputs, field, law, delay, until=0.5)
    late = closed_loop(params, inputs, field, law, delay, until=0.5, lateness=[2, 0, 5, 1], wall_step=1_234_567)
    assert prompt.blocked == 0 and late.blocked > 2 * len(late.periods), "the late run did wait"
    assert late.at_bound > 0, "the late run stood at the bound the gate sets"
    _check_answers_act_at_stamp_plus_delay(late, field, law)
    assert _record(late) == _record(prompt)


@pytest.mark.parametrize("case", CASES)
def test_pausing_and_stepping_a_closed_loop_changes_nothing(case: str) -> None:
    """Pauses, steps of odd lengths (one ending exactly at a period's end) and a
    resume, in the middle of the loop: the same record as the run left alone."""
    params, inputs, field, law = CASES[case]
    alone = closed_loop(params, inputs, field, law, 0.005)
    controls = {7: ("pause", 0.0), 9: ("step", 0.0013), 12: ("step", 0.0137), 13: ("step", 0.002),
                20: ("step", 0.011), 30: ("resume", 0.0), 40: ("pause", 0.0), 41: ("resume", 0.0)}
    held = closed_loop(params, inputs, field, law, 0.005, controls=controls, lateness=[1])
    assert held.blocked > alone.blocked
    assert _record(held) == _record(alone)


@settings(max_examples=40, deadline=None)
@given(delay=st.floats(0.0, 0.05), lateness=st.lists(st.integers(0, 4), min_size=1, max_size=8),
       frequency=st.one_of(st.sampled_from([50.0, 30.0, 47.3]), st.floats(5.0, 120.0)),
       wall_step=st.integers(0, 10**8))
def test_any_delay_and_any_lateness_give_the_record_of_prompt_answers(
        delay: float, lateness: list[int], frequency: float, wall_step: int) -> None:
    """For any actuation delay in [0, 50 ms], any pattern of late answers and any
    wall clock, the (t, Pa) commands and the period means are those of the run
    answered at once, and every command acts at its sample plus the delay."""
    inputs = Inputs(excitation_frequency=frequency)
    prompt = closed_loop(SliderParams(), inputs, PA, pa_law, delay)
    late = closed_loop(SliderParams(), inputs, PA, pa_law, delay, lateness=lateness, wall_step=wall_step)
    assert late.blocked > 0
    assert [(o.t, o.values[PA]) for o in late.outcomes] == [(o.t, o.values[PA]) for o in prompt.outcomes]
    assert [p.mean_velocity for p in late.periods] == [p.mean_velocity for p in prompt.periods]
    assert late.state == prompt.state
    for outcome, period in zip(late.outcomes, late.periods):
        assert to_ns(outcome.t) == to_ns(period.t) + late.gate.delay_ns


@settings(max_examples=25, deadline=None)
@given(case=st.sampled_from(list(CASES)), delay=st.floats(0.0, 0.05), start=st.integers(0, 10),
       steps=st.lists(st.one_of(st.floats(1e-9, 0.05), st.sampled_from([0.005, 0.015, 0.02])), max_size=6),
       gap=st.integers(1, 3), lateness=st.one_of(st.none(), st.lists(st.integers(0, 3), min_size=1, max_size=4)))
def test_any_pause_and_steps_give_the_record_of_the_run_left_alone(
        case: str, delay: float, start: int, steps: list[float], gap: int, lateness: list[int] | None) -> None:
    """A pause anywhere, steps of any length issued every ``gap`` iterations (so some
    while the one before is under way), and a resume once they are done (300 iterations
    later: a resume during a step is refused as 'not paused')."""
    params, inputs, field, law = CASES[case]
    alone = closed_loop(params, inputs, field, law, delay)
    controls = {start: ("pause", 0.0)}
    for i, length in enumerate(steps):
        controls[start + 1 + i * gap] = ("step", length)
    controls[start + 1 + len(steps) * gap + 300] = ("resume", 0.0)
    held = closed_loop(params, inputs, field, law, delay, controls=controls, lateness=lateness)
    assert held.blocked > 0, "the pause came before the end (start <= 10 < the 15 periods of 0.3 s)"
    assert _record(held) == _record(alone)


# -- settings ---------------------------------------------------------------------------


def test_participants_are_parsed_and_an_unknown_one_is_named() -> None:
    assert participants(" controller , scheduler ") == frozenset({CONTROLLER, SCHEDULER})
    assert participants("") == frozenset()
    with pytest.raises(ParameterError, match="lockstep_participants = 'controller,plant'") as error:
        participants("controller,plant")
    assert "'plant'" in str(error.value)


def test_the_gate_refuses_a_delay_out_of_range() -> None:
    with pytest.raises(ParameterError, match="actuation_delay"):
        _gate(-0.001, CONTROLLER)
    assert to_ns(0.0333) == 33_300_000 and _gate(0.0333, CONTROLLER).delay_ns == 33_300_000


def test_the_gate_reports_its_figures() -> None:
    gate = _gate(0.005, CONTROLLER)
    gate.sample(20 * MS)
    gate.answer(20 * MS, [])
    gate.answer(20 * MS, [])
    values = gate.values()
    expected = {"lockstep": True, "actuation_delay": 0.005, "lockstep_answers": 1, "lockstep_stale_answers": 1,
                "lockstep_scheduled": 0, "lockstep_waited_s": 0.0, "lockstep_promise": math.inf}
    assert {key: values.get(key) for key in expected} == expected
    scheduler = _gate(0.0, SCHEDULER)
    assert scheduler.promise(30 * MS, [], 0) == ""
    assert scheduler.values()["lockstep_promise"] == 0.03


def test_a_report_counts_the_stamped_messages_stamped_by_its_time_whenever_they_came() -> None:
    """Two runs, one whose scheduler's messages all came at once, one whose came one by one
    (each only once the slider stood at the one before): the reports at the same simulation
    times count the same, those stamped before their time."""
    stamps = [10 * MS, 20 * MS, 20 * MS, 40 * MS]
    early = _gate(0.0, SCHEDULER)
    for stamp in stamps:
        assert early.promise(stamp, [], 0) == ""
    late = _gate(0.0, SCHEDULER)
    counts = {}
    for t_ns in (5 * MS, 10 * MS, 25 * MS, 40 * MS):
        for stamp in stamps[:sum(stamp < t_ns for stamp in stamps) + 1][late.scheduled:]:
            assert late.promise(stamp, [], 0) == ""  # what has come before t_ns, and the one that let it get there
        counts[t_ns] = (early.values(t_ns)["lockstep_scheduled"], late.values(t_ns)["lockstep_scheduled"])
    assert counts == {5 * MS: (0, 0), 10 * MS: (0, 0), 25 * MS: (3, 3), 40 * MS: (3, 3)}
    assert early.scheduled == late.scheduled == 4
