"""The live view's Foxglove side: its channels, who subscribes to them, and
the records served onto them (:mod:`friction_sim.io.live`).

:class:`LiveChannels` holds one Foxglove channel per fully qualified topic
(advertised on first use with the topic's ``ros2msg`` schema) and serves a
sink record onto them on the view's background thread: built
(:func:`~friction_sim.io.recordwriter.record_messages`), encoded to CDR
only for a channel some client subscribes to (the states written into the
recording's fixed layouts), and logged at the record's simulation time.  A
record no message can hold is counted bad and warned of once per kind; a
failure of the server raises (it ends the view's thread).

:class:`Subscriptions` is the SDK's listener: it keeps which client
subscribes to which topic, so that the caller's side can skip a record no
one watches with a set test.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Sequence
from typing import Any

import foxglove
from foxglove.websocket import ChannelView, Client, ServerListener

from friction_sim.core.model.events import Mode, SliderState
from friction_sim.errors import one_line
from friction_sim.io import cdr
from friction_sim.io.bagfile import MAX_STAMP_NS
from friction_sim.io.messages import (
    STATE_TOPICS,
    TOPIC_TYPES,
    fill_state_messages,
    seconds_to_ns,
    state_messages,
)
from friction_sim.io.recordwriter import (
    STATE_VALUES,
    qualified_topic,
    record_kind,
    record_messages,
    record_topics,
    state_row,
    state_row_builder,
)
from friction_sim.io.sinks import Record, StatesRecord
from friction_sim.io.typesupport import message_definition, message_type_name

_log = logging.getLogger("friction_sim.io.live")


class LiveChannels:
    """The channels of one live view and the serving of records onto them.

    ``namespace`` qualifies relative topic names and ``node`` is the name the
    parameter events carry; ``lock`` and ``counts`` are the view's (skipped,
    bad, encoded and sent messages are counted here); ``url`` names the view
    in warnings.  :meth:`serve` runs on the view's one background thread;
    :meth:`topic`, :meth:`qualified` and :attr:`advertised` are read on the
    caller's too (``advertised`` is replaced whole: read lock-free).
    """

    def __init__(self, context: foxglove.Context, namespace: str, node: str, lock: threading.Lock,
                 counts: dict[str, int], url: str) -> None:
        self._context = context
        self._namespace = namespace
        self._node = node
        self._lock = lock
        self._counts = counts
        self._url = url
        self._topics: dict[str, str] = {}
        self.state_topics = tuple(self.topic(topic) for topic in STATE_TOPICS)
        self.advertised: frozenset[str] = frozenset()  # topics with a channel (replaced whole: read lock-free)
        self._channels: dict[str, tuple[foxglove.Channel, str]] = {}  # topic -> (channel, type name)
        self._layouts: dict[str, tuple[cdr.FixedLayout, ...] | None] = {}  # frame_id -> state layouts
        self._templates = state_messages(SliderState(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, Mode.STUCK))  # refilled
        self._warned: set[str] = set()

    # -- names -------------------------------------------------------------------------

    def topic(self, topic: str) -> str:
        """The fully qualified name of ``topic`` (cached)."""
        name = self._topics.get(topic)
        if name is None:
            name = self._topics[topic] = qualified_topic(self._namespace, topic)
        return name

    def qualified(self, record: Record) -> tuple[str, ...]:
        """The fully qualified names of ``record``'s topics."""
        if isinstance(record, StatesRecord):
            return self.state_topics
        return tuple(self.topic(topic) for topic in record_topics(record))

    # -- channels ----------------------------------------------------------------------

    def channel(self, topic: str, type_name: str) -> foxglove.Channel:
        """The channel of ``topic``, advertised on first use with ``type_name``'s schema."""
        entry = self._channels.get(topic)
        if entry is None:
            schema = foxglove.Schema(name=type_name, encoding="ros2msg",
                                     data=message_definition(type_name).encode("utf-8"))
            channel = foxglove.Channel(topic, schema=schema, message_encoding="cdr", context=self._context)
            entry = self._channels[topic] = (channel, type_name)
            with self._lock:
                self.advertised = self.advertised | {topic}
        elif entry[1] != type_name:
            raise ValueError(f"topic {topic} carries {entry[1]}, not {type_name}")
        return entry[0]

    def close(self) -> None:
        """Close every channel (the view's thread has ended)."""
        for channel, _ in list(self._channels.values()):
            channel.close()

    # -- serving (the view's background thread) ------------------------------------------

    def serve(self, record: Record, size: int) -> None:
        """Build, encode and log the messages of one record."""
        if isinstance(record, StatesRecord):
            self._serve_states(record.states, record.frame_id)
            return
        try:
            messages = record_messages(record, self._node)
        except Exception as error:  # noqa: BLE001 - one bad record must not end the live view
            self._count_bad(size, record_kind(record), one_line(error, with_type=True))
            return
        for topic, msg, log_time_ns in messages:
            self._log_message(self.topic(topic), msg, log_time_ns)

    def _serve_states(self, states: Sequence[SliderState], frame_id: str) -> None:
        """Log states as pose, velocity and friction_force, encoding only the
        watched topics: written into the fixed layout of each message (the
        bytes rosbags serializes, as the recording writes them: 2 us a state
        rather than 15), or serialized one by one if there is none."""
        channels = [self.channel(topic, TOPIC_TYPES[name]) for topic, name in zip(self.state_topics, STATE_TOPICS)]
        watched = [index for index, channel in enumerate(channels) if channel.has_sinks()]
        with self._lock:
            self._counts["skipped"] += (3 - len(watched)) * len(states)
        if not watched:
            return
        layouts = self._state_layouts(frame_id)
        for state in states:
            try:
                ns = seconds_to_ns(state.t)
                if not 0 <= ns <= MAX_STAMP_NS:
                    raise ValueError(f"time {state.t!r} s is outside ROS time")
                if layouts is not None:
                    values = state_row(state)
                    payloads = [layouts[index].encode_one(ns, values) for index in watched]
                else:
                    fill_state_messages(state, frame_id, *self._templates)
                    payloads = [cdr.serialize(self._templates[index]) for index in watched]
            except Exception as error:  # noqa: BLE001 - one bad record must not end the live view
                self._count_bad(len(watched), "state", one_line(error, with_type=True))
                continue
            for index, data in zip(watched, payloads):
                self._counts["encoded"] += 1
                channels[index].log(data, log_time=ns)  # an SDK failure here ends the thread (LiveView._run)
                self._counts["sent"] += 1

    def _state_layouts(self, frame_id: str) -> tuple[cdr.FixedLayout, ...] | None:
        """The fixed layouts of the three state messages in ``frame_id`` (cached;
        None: none, serialize one at a time), as the recording's writer finds them."""
        if frame_id not in self._layouts:
            try:
                layouts = cdr.fixed_layouts(state_row_builder(frame_id), len(STATE_VALUES))
            except Exception:  # noqa: BLE001 - no layout: the slower path serializes each message
                layouts = None
            self._layouts[frame_id] = layouts if layouts is not None and len(layouts) == 3 else None
        return self._layouts[frame_id]

    def _log_message(self, topic: str, msg: Any, log_time_ns: int) -> None:
        """Encode ``msg`` and log it on ``topic``'s channel if a client
        subscribes to it (made on first use); a record no message can hold is
        counted bad, a failure of the server ends the thread."""
        try:
            channel = self.channel(topic, message_type_name(type(msg)))
            if not 0 <= log_time_ns <= MAX_STAMP_NS:
                raise ValueError(f"log time {log_time_ns} ns is outside ROS time")
            if not channel.has_sinks():
                with self._lock:
                    self._counts["skipped"] += 1
                return
            data = cdr.serialize(msg)
        except Exception as error:  # noqa: BLE001 - one bad record must not end the live view
            self._count_bad(1, topic, one_line(error, with_type=True))
            return
        self._counts["encoded"] += 1
        channel.log(data, log_time=log_time_ns)  # an SDK failure here ends the thread (LiveView._run)
        self._counts["sent"] += 1

    def _count_bad(self, messages: int, what: str, why: str) -> None:
        """Count messages no message could hold (warned once per kind)."""
        with self._lock:
            self._counts["bad"] += messages
        if what not in self._warned:
            self._warned.add(what)
            _log.warning("live view %s: dropped a %s record: %s", self._url, what, why)


class Subscriptions(ServerListener):
    """Which client subscribes to which topic, as the SDK tells (on its own threads).

    ``live`` is the set of topics some client subscribes to, replaced whole,
    so the caller's side reads it without a lock.
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._topics: dict[int, set[str]] = {}  # client id -> topics
        self.live: frozenset[str] = frozenset()

    @property
    def clients(self) -> int:
        """Clients subscribed to at least one channel (the SDK tells of
        subscriptions, not of connections: a client that subscribes to
        nothing is not counted)."""
        with self._lock:
            return sum(1 for topics in self._topics.values() if topics)

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        self._note(client.id, channel.topic, True)

    def on_unsubscribe(self, client: Client, channel: ChannelView) -> None:
        self._note(client.id, channel.topic, False)

    def _note(self, client: int, topic: str, subscribed: bool) -> None:
        """Note a client's (un)subscription."""
        with self._lock:
            topics = self._topics.setdefault(client, set())
            if subscribed:
                topics.add(topic)
            else:
                topics.discard(topic)
                if not topics:
                    del self._topics[client]
            self.live = frozenset().union(*self._topics.values())
