"""The Foxglove live view (friction_sim.io.live) seen by a real client over a real socket.

The client (test/foxglove_client.py) speaks the SDK's protocol with the
websockets package and decodes payloads with mcap-ros2-support from the
advertised schema text, so these tests check what Foxglove would see, not
what friction_sim thinks it sent.  Every server binds 127.0.0.1 on a port
the OS chooses.
"""

from __future__ import annotations

import contextlib
import logging
import math
import socket
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from mcap.reader import make_reader
from std_msgs.msg import Float64, String

from friction_sim.core.model.commands import Command, Outcome
from friction_sim.core.model.events import Event, EventKind, Mode, SliderState
from friction_sim.core.model.records import PeriodSummary
from friction_sim.errors import LiveViewError
from friction_sim.io import cdr
from friction_sim.io.live import ADVERTISED, LiveView
from friction_sim.io.messages import TOPIC_TYPES, seconds_to_ns, state_messages
from friction_sim.io.recorder import Recorder
from friction_sim.io.sinks import (
    ClockRecord,
    CommandRecord,
    EventRecord,
    MessageRecord,
    ParametersRecord,
    PeriodRecord,
    StatesRecord,
)
from friction_sim.io.typesupport import message_definition

from foxglove_client import FoxgloveClient, Received

NS = "/feeder1"
STATE_TOPICS = [f"{NS}/pose", f"{NS}/velocity", f"{NS}/friction_force"]


def state(i: int) -> SliderState:
    """A state whose every number differs from the others' and from every other state's."""
    t = 0.001 * i
    return SliderState(t, x=1e-3 * i + 1 / 3, v=-2e-4 * i + 0.1, acceleration=0.0, friction_force=-0.25 - i / 7,
                       normal_force=9.5 + i / 11, phase=0.0, mode=Mode.FORWARD, z=1e-5 * i, vz=2e-5 * i + 1e-7)


EVENT = Event(0.0125, EventKind.SLIP_START, 0.0123456789, 1.25, Mode.STUCK, Mode.FORWARD)
ACCEPTED = Outcome(Command(0.013, "drive_force", {"drive_force": 0.7}))
REFUSED = Outcome(Command(0.014, "excitation_amplitude", {"excitation_amplitude": -4.0}),
                  "excitation_amplitude = -4.0 rejected: must be >= 0 N")
PERIOD = PeriodSummary(n=3, t=0.015, mean_velocity=2.5e-4, window_periods=2, stick_fraction=0.25)
PARAMETERS = {"mass": 1.25, "mu": 0.3, "landing_friction": "coulomb"}


def diagnostics(t: float) -> DiagnosticArray:
    """A message no sink method makes: what the node hands to write()."""
    msg = DiagnosticArray()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(seconds_to_ns(t), 1_000_000_000)
    msg.status = [DiagnosticStatus(level=DiagnosticStatus.OK, name="slider", message="running",
                                   values=[KeyValue(key="tick_rate", value="1000.0")])]
    return msg


@pytest.fixture
def view() -> Iterator[LiveView]:
    live = LiveView(0, namespace=NS)
    yield live
    live.close()


def wait_until(condition: Callable[[], object], timeout: float = 5.0) -> bool:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.005)  # poll interval: waiting for the condition
    return True


def subscribed(client: FoxgloveClient, view: LiveView, *topics: str) -> None:
    """Subscribe and wait until the server has taken the subscriptions."""
    client.subscribe(*topics)
    live = view._subscriptions  # noqa: SLF001 - the listener's record
    assert wait_until(lambda: set(topics) <= live.live), live.live


def advertised(view: LiveView, *topics: str) -> None:
    """Wait until the view has made the channels of ``topics`` (first use).

    A client that connects while a channel is being made may be told of it
    and yet be refused when it subscribes ("attempted to subscribe to unknown
    channel": foxglove-sdk 0.30.3), so the tests connect after that."""
    channels = view._channels  # noqa: SLF001 - its own record
    assert wait_until(lambda: set(topics) <= channels.advertised), channels.advertised


def by_topic(received: list[Received]) -> dict[str, list[Received]]:
    out: dict[str, list[Received]] = {}
    for message in received:
        out.setdefault(message.topic, []).append(message)
    return out


# -- what a client sees -------------------------------------------------------------------


def test_channels_are_advertised_as_a_recording_names_and_types_them(view: LiveView) -> None:
    with FoxgloveClient(view.url) as client:
        channels = client.wait_for_channels(*(f"{NS}/{topic}" for topic in ADVERTISED))
        client.collect(0.1)
        assert sorted(client.channels) == sorted(channels)  # nothing else until its first record
    assert view.url == f"ws://127.0.0.1:{view.port}" and view.port > 0
    for topic, channel in channels.items():
        type_name = TOPIC_TYPES[topic.rsplit("/", 1)[1]]
        assert channel["schemaName"] == type_name
        assert channel["schemaEncoding"] == "ros2msg"
        assert channel["encoding"] == "cdr"
        assert channel["schema"] == message_definition(type_name)  # the full rosbag2 text, dependencies too
    assert "MSG: std_msgs/Header" in channels[f"{NS}/pose"]["schema"]


def test_states_reach_a_client_with_their_values_and_times(view: LiveView) -> None:
    states = [state(i) for i in range(1, 41)]
    with FoxgloveClient(view.url) as client:
        subscribed(client, view, *STATE_TOPICS)
        for i in range(0, len(states), 4):  # as the node hands them: a few per call
            view.write(StatesRecord(tuple(states[i:i + 4]), "slideway"))
        received = by_topic(client.collect(until=lambda got: len(got) >= 3 * len(states)))
    assert [len(received[topic]) for topic in STATE_TOPICS] == [len(states)] * 3
    for s, pose, velocity, force in zip(states, *(received[topic] for topic in STATE_TOPICS)):
        ns = seconds_to_ns(s.t)
        assert pose.log_time_ns == velocity.log_time_ns == force.log_time_ns == ns
        for message in (pose, velocity, force):
            stamp = message.message.header.stamp
            assert stamp.sec * 1_000_000_000 + stamp.nanosec == ns
            assert message.message.header.frame_id == "slideway"
        assert (pose.message.pose.position.x, pose.message.pose.position.z) == (s.x, s.z)
        assert (velocity.message.twist.linear.x, velocity.message.twist.linear.z) == (s.v, s.vz)
        assert (force.message.wrench.force.x, force.message.wrench.force.z) == (s.friction_force, s.normal_force)
        # the very bytes friction_sim's encoder (that of the recording) makes
        assert [pose.payload, velocity.payload, force.payload] == [cdr.serialize(m) for m in state_messages(s)]
    assert view.sent == view.encoded == 3 * len(states)
    assert view.dropped == 0 and view.error is None


def test_events_commands_parameters_and_written_messages_arrive_decoded(view: LiveView) -> None:
    skipped = view.skipped
    view.write(MessageRecord("diagnostics", diagnostics(0.0), 0))  # first use: advertises /feeder1/diagnostics
    view.write(CommandRecord(ACCEPTED, "slideway"))  # likewise /feeder1/drive_force
    view.write(ClockRecord(0))  # likewise /clock (absolute: not in the namespace); its message is built then
    advertised(view, f"{NS}/diagnostics", f"{NS}/drive_force", "/clock")
    assert wait_until(lambda: view.skipped == skipped + 3)  # (served to no one, on the view's thread)
    view.write(ClockRecord(1_000_000))  # nobody subscribes: skipped at once, no message built
    assert view.skipped == skipped + 4
    topics = [f"{NS}/{name}" for name in ("events", "drive_force", "rejected_commands", "mean_velocity",
                                          "parameters", "diagnostics")] + ["/clock"]
    with FoxgloveClient(view.url) as client:
        subscribed(client, view, *topics)
        assert client.channels[f"{NS}/diagnostics"]["schemaName"] == "diagnostic_msgs/msg/DiagnosticArray"
        view.write(EventRecord(EVENT))
        view.write(CommandRecord(ACCEPTED, "slideway"))
        view.write(CommandRecord(REFUSED, "slideway"))
        view.write(PeriodRecord(PERIOD, "slideway"))
        view.write(ParametersRecord(PARAMETERS, 0.016, True))
        assert view.write(MessageRecord("diagnostics", diagnostics(0.017), seconds_to_ns(0.017)))
        view.write(ClockRecord(18_000_000))
        received = {m.topic: m for m in client.collect(until=lambda got: len(got) >= len(topics))}
    assert sorted(received) == sorted(topics)

    event = received[f"{NS}/events"]
    assert event.log_time_ns == seconds_to_ns(EVENT.t)
    assert (event.message.name, event.message.message, event.message.level) == ("slip_start", "stuck -> forward", 0)
    values = {kv.key: kv.value for kv in event.message.values}
    assert float(values["x"]) == EVENT.x and float(values["t"]) == EVENT.t and values["after"] == "forward"

    drive = received[f"{NS}/drive_force"]
    assert drive.log_time_ns == seconds_to_ns(ACCEPTED.t) and drive.message.data == 0.7

    refused = received[f"{NS}/rejected_commands"]
    assert refused.log_time_ns == seconds_to_ns(REFUSED.t)
    assert refused.message.level == 1 and refused.message.name == "excitation_amplitude"
    assert refused.message.message == REFUSED.reason
    assert [(kv.key, kv.value) for kv in refused.message.values] == [("excitation_amplitude", "-4.0")]

    period = received[f"{NS}/mean_velocity"]
    assert period.log_time_ns == seconds_to_ns(PERIOD.t) and period.message.twist.linear.x == PERIOD.mean_velocity

    parameters = received[f"{NS}/parameters"]
    assert parameters.log_time_ns == seconds_to_ns(0.016) and not parameters.message.new_parameters
    changed = {p.name: p.value for p in parameters.message.changed_parameters}
    assert changed["mass"].double_value == 1.25 and changed["landing_friction"].string_value == "coulomb"

    assert received["/clock"].log_time_ns == 18_000_000 and received["/clock"].message.clock.nanosec == 18_000_000
    assert client.channels["/clock"]["schemaName"] == "rosgraph_msgs/msg/Clock"

    diag = received[f"{NS}/diagnostics"]
    assert diag.log_time_ns == seconds_to_ns(0.017)
    assert diag.message.status[0].values[0].key == "tick_rate" and diag.message.status[0].message == "running"


def test_a_client_gets_the_bytes_a_recording_holds(view: LiveView, tmp_path: Path) -> None:
    """The same records to a recorder and to the live view: every payload the
    client gets is the message the recording holds at that topic and time."""
    path = tmp_path / "run.mcap"
    sinks = [view, Recorder(path, metadata={"mass": 1.0}, namespace=NS)]
    view.write(MessageRecord("target_speed", Float64(data=0.0), 0))
    advertised(view, f"{NS}/target_speed")
    topics = [*STATE_TOPICS, *(f"{NS}/{name}" for name in ("events", "rejected_commands", "mean_velocity",
                                                           "parameters", "target_speed"))]
    with FoxgloveClient(view.url) as client:
        subscribed(client, view, *topics)
        for sink in sinks:
            sink.write(ParametersRecord(PARAMETERS, 0.0, False))
            sink.write(StatesRecord(tuple(state(i) for i in range(1, 11)), "slideway"))
            sink.write(EventRecord(EVENT))
            sink.write(CommandRecord(REFUSED, "slideway"))
            sink.write(PeriodRecord(PERIOD, "slideway"))
            sink.write(MessageRecord("target_speed", Float64(data=3e-4), seconds_to_ns(0.02)))
        sinks[1].close()
        expected = 30 + 5
        received = client.collect(until=lambda got: len(got) >= expected)
    with path.open("rb") as stream:
        recorded = {(channel.topic, message.log_time): message.data
                    for _, channel, message in make_reader(stream).iter_messages()}
    assert len(received) == expected == len(recorded)
    for message in received:
        assert recorded[(message.topic, message.log_time_ns)] == message.payload, message.topic


# -- the cost to the caller ----------------------------------------------------------------


def test_nothing_is_encoded_without_a_subscriber_and_a_burst_never_blocks(view: LiveView) -> None:
    s = state(5)
    with FoxgloveClient(view.url) as client:
        subscribed(client, view, f"{NS}/events")  # a client, but not on the state topics
        for _ in range(100_000):
            view.write(StatesRecord((s,), "slideway"))
    assert view.encoded == 0 and view.sent == 0
    assert view.skipped == 300_000 and view.dropped == 0


def test_a_burst_beyond_what_the_thread_encodes_is_dropped_and_counted_never_waits(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The serving thread is held inside its first record for the whole burst: the
    caller still gets through all 100k calls (it never waits for the thread: the
    calls run in a thread of their own that must end while the server is held),
    the queue keeps at most its size, and the rest is dropped and counted."""
    view = LiveView(0, namespace=NS, queue_size=3000)
    states = [state(i) for i in range(1, 100_001)]
    held, release = threading.Event(), threading.Event()
    channels = view._channels  # noqa: SLF001 - hold the real serving step
    serve = channels.serve

    def held_serve(item: object, size: int) -> None:
        held.set()
        release.wait(120.0)
        serve(item, size)  # type: ignore[arg-type]

    monkeypatch.setattr(channels, "serve", held_serve)
    try:
        with FoxgloveClient(view.url) as client:
            subscribed(client, view, f"{NS}/pose")
            view.write(StatesRecord((states[0],), "slideway"))
            assert wait_until(held.is_set)
            burst = threading.Thread(target=lambda: [view.write(StatesRecord((s,), "slideway")) for s in states[1:]])
            burst.start()
            burst.join(timeout=120.0)  # a hang guard: the burst ends while the server is still held
            assert not burst.is_alive() and not release.is_set(), "the caller waited for the serving thread"
            assert view.dropped >= len(states) - 1 - 3000
            release.set()
            received = client.collect(until=lambda got: len(got) >= 1 + 3000 // 3, timeout=30.0)
    finally:
        release.set()
        view.close()
    # each message offered is accounted for once: sent, skipped (nobody on velocity and friction_force), dropped
    assert view.sent + view.skipped + view.dropped == 300_000
    assert view.sent == view.encoded > 0
    times = [message.log_time_ns for message in received]
    assert times and times == sorted(set(times))  # gaps where records were dropped, never reordered


# -- the server ----------------------------------------------------------------------------


def test_a_busy_port_is_refused_naming_the_field_and_leaves_nothing_running(view: LiveView) -> None:
    threads = threading.active_count()
    with pytest.raises(LiveViewError) as caught:
        LiveView(view.port)
    error = caught.value
    assert (error.field, error.value) == ("foxglove_port", view.port)
    assert str(error).startswith(f"foxglove_port = {view.port} rejected: port {view.port} on 127.0.0.1 is "
                                 "already in use")
    assert "Address already in use" in error.reason
    assert threading.active_count() == threads
    with socket.socket() as other, pytest.raises(LiveViewError, match="already in use"):  # any program's port
        other.bind(("127.0.0.1", 0))
        other.listen()
        LiveView(other.getsockname()[1])


@pytest.mark.parametrize("address", ["", "not an address", "999.1.1.1", "-bad-.example", 7])
def test_an_address_that_is_no_address_is_refused_without_a_lookup(address: object) -> None:
    with pytest.raises(LiveViewError, match=r"^foxglove_address = .* rejected: must be an IP address") as caught:
        LiveView(0, address)  # type: ignore[arg-type]
    assert caught.value.field == "foxglove_address"


def test_an_address_of_another_machine_is_refused_with_the_os_reason() -> None:
    # 192.0.2.1 (TEST-NET-1) is no interface here: the bind fails at once and nothing is sent
    with pytest.raises(LiveViewError) as caught:
        LiveView(0, "192.0.2.1")
    assert caught.value.field == "foxglove_address" and caught.value.value == "192.0.2.1"
    assert "Cannot assign requested address" in str(caught.value)


def test_other_topics_can_be_advertised_at_start_too() -> None:
    with LiveView(0, namespace=NS, advertise=["events", ("/clock", "rosgraph_msgs/msg/Clock"),
                                              ("diagnostics", "diagnostic_msgs/msg/DiagnosticArray")]) as view, \
            FoxgloveClient(view.url) as client:
        client.wait_for_channels(f"{NS}/events", "/clock", f"{NS}/diagnostics")
        client.collect(0.1)
        assert sorted(client.channels) == ["/clock", f"{NS}/diagnostics", f"{NS}/events"]
        assert client.channels["/clock"]["schemaName"] == "rosgraph_msgs/msg/Clock"
    with pytest.raises(LiveViewError, match=r"^advertise = \['clock'\] rejected: not topics of a recording"):
        LiveView(0, advertise=["clock"])


@pytest.mark.parametrize("port", [-1, 65536, 1.5, True, "8765"])
def test_a_port_that_is_no_port_is_refused(port: object) -> None:
    with pytest.raises(LiveViewError, match=r"^foxglove_port = .* rejected: must be a TCP port in 0\.\.65535"):
        LiveView(port)  # type: ignore[arg-type]


def test_close_is_idempotent_frees_the_port_and_refuses_later_records() -> None:
    view = LiveView(0)
    port = view.port
    view.write(MessageRecord("diagnostics", diagnostics(0.0), 0))  # queued (first use) until closed
    view.close()
    view.close()
    assert view.write(MessageRecord("diagnostics_2", diagnostics(0.0), 0)) is False
    # The port is free again: a server binds it (as a server binds, SO_REUSEADDR: no listener is
    # left, whatever connections linger).  Held by this socket, not released and bound again later.
    with socket.socket() as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        probe.bind(("127.0.0.1", port))
        probe.listen()


def test_two_views_in_one_process_share_no_channels() -> None:
    with LiveView(0) as first, LiveView(0) as second:
        first.write(MessageRecord("only_first", Float64(data=1.0), 0))
        second.write(MessageRecord("only_second", Float64(data=2.0), 0))
        advertised(first, "/only_first")
        advertised(second, "/only_second")
        with FoxgloveClient(first.url) as a, FoxgloveClient(second.url) as b:
            a.wait_for_channels("/only_first")
            b.wait_for_channels("/only_second")
            a.collect(0.2)
            b.collect(0.2)
            assert "/only_second" not in a.channels and "/only_first" not in b.channels
            subscribed(a, first, "/pose")
            subscribed(b, second, "/pose")
            first.write(StatesRecord((state(1),), "one"))
            second.write(StatesRecord((state(2),), "two"))
            got_a, got_b = a.collect(until=lambda got: got), b.collect(until=lambda got: got)
    assert [m.message.header.frame_id for m in got_a] == ["one"]
    assert [m.message.header.frame_id for m in got_b] == ["two"]


def test_a_client_that_sends_garbage_or_vanishes_does_not_stop_the_others(view: LiveView) -> None:
    with FoxgloveClient(view.url) as steady:
        subscribed(steady, view, f"{NS}/pose")
        rude = FoxgloveClient(view.url).__enter__()
        subscribed(rude, view, f"{NS}/pose")
        assert wait_until(lambda: view.clients == 2)
        view.write(StatesRecord((state(1),), "slideway"))
        rude.ws.send("{not json")
        rude.ws.send(b"\xff\x00\x01garbage")
        rude.ws.send('{"op": "subscribe", "subscriptions": [{"id": 1, "channelId": 99999}]}')
        rude.ws.socket.shutdown(socket.SHUT_RDWR)  # gone mid-stream, no closing handshake
        rude.ws.socket.close()
        for i in range(2, 200):
            view.write(StatesRecord((state(i),), "slideway"))
        received = steady.collect(until=lambda got: len(got) >= 199)
        assert wait_until(lambda: view.clients == 1)
        with contextlib.suppress(Exception):
            rude.close()
    assert [m.log_time_ns for m in received] == [seconds_to_ns(state(i).t) for i in range(1, 200)]
    assert view.error is None
    assert wait_until(lambda: view.clients == 0)


def test_a_record_no_message_holds_is_dropped_and_counted(view: LiveView, caplog: pytest.LogCaptureFixture) -> None:
    view.write(MessageRecord("mixed", Float64(data=1.0), 0))
    advertised(view, f"{NS}/mixed")
    with FoxgloveClient(view.url) as client:
        subscribed(client, view, f"{NS}/mixed", *STATE_TOPICS)
        view.write(MessageRecord("mixed", String(data="other type"), 1))  # a topic keeps its first type
        view.write(MessageRecord("mixed", Float64(data=2.0), -5))  # before time 0: no ROS stamp
        view.write(StatesRecord((SliderState(math.nan, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, Mode.STUCK),), "slideway"))
        view.write(MessageRecord("mixed", Float64(data=3.0), 7))
        received = client.collect(until=lambda got: got)
    assert [(m.topic, m.log_time_ns, m.message.data) for m in received] == [(f"{NS}/mixed", 7, 3.0)]
    assert view.dropped == 1 + 1 + 3 and view.error is None
    assert "carries std_msgs/msg/Float64, not std_msgs/msg/String" in caplog.text


def test_a_thread_that_dies_says_why_and_the_view_refuses_records(
        view: LiveView, caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch) -> None:
    def broken(item: object, size: int) -> None:
        raise RuntimeError("encoder exploded\nsecond line")

    monkeypatch.setattr(view._channels, "serve", broken)  # noqa: SLF001 - break the real serving step
    with caplog.at_level(logging.ERROR, logger="friction_sim.io.live"), FoxgloveClient(view.url) as client:
        subscribed(client, view, f"{NS}/pose")
        view.write(StatesRecord((state(1),), "slideway"))
        assert wait_until(lambda: view.error is not None)
        client.collect(until=lambda _: bool(client.statuses), timeout=2.0)
        assert view.dropped == 3  # the record the thread died on
        view.write(StatesRecord((state(2),), "slideway"))  # still subscribed: refused, counted
        assert view.write(MessageRecord("anything", Float64(data=0.0), 0)) is False
        assert view.dropped == 3 + 3 + 1
    assert view.error == "live view stopped: RuntimeError: encoder exploded"
    assert view.stats()["live_view_error"] == view.error
    assert [r.getMessage() for r in caplog.records if r.name == "friction_sim.io.live"] == [
        f"{view.error} ({view.url})"]
    assert client.statuses and client.statuses[0]["level"] == 2 and "encoder exploded" in client.statuses[0]["message"]


def test_stats_for_the_diagnostics(view: LiveView) -> None:
    assert view.stats() == {"live_view_url": view.url, "live_view_clients": 0, "live_view_sent": 0,
                            "live_view_dropped": 0, "live_view_thinned": 0, "live_view_error": ""}
    with FoxgloveClient(view.url) as client:
        subscribed(client, view, f"{NS}/pose", f"{NS}/events")
        view.write(StatesRecord((state(1),), "slideway"))
        client.collect(until=lambda got: got)
        assert view.stats()["live_view_clients"] == 1 and view.stats()["live_view_sent"] == 1


def test_a_flood_of_commands_is_thinned_for_the_viewer_and_counted() -> None:
    """10,000 refused commands in a burst: a subscribed client gets at most
    COMMANDS_PER_SECOND of them a second, the rest are counted as thinned."""
    from friction_sim.io.live import COMMANDS_PER_SECOND

    with LiveView(0, namespace=NS) as view, FoxgloveClient(view.url) as client:
        subscribed(client, view, f"{NS}/rejected_commands")
        for k in range(10_000):
            refused = Outcome(Command(k * 1e-4, "drive_force", {"drive_force": math.nan}), "nan")
            view.write(CommandRecord(refused, "slideway"))
        got = client.collect(1.0)
        assert 0 < len(got) <= COMMANDS_PER_SECOND * 2
        assert view.thinned >= 10_000 - 2 * COMMANDS_PER_SECOND
        assert view.stats()["live_view_thinned"] == view.thinned
