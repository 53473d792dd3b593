"""Live view: a run served to Foxglove over the Foxglove SDK's WebSocket server.

:class:`LiveView` is a :class:`~friction_sim.io.sinks.Sink` beside the
recorder.  It serves the same topics with the same messages as a recording
(:mod:`friction_sim.io.recorder`), so Foxglove shows a live run exactly as
it shows the file afterwards:

* one channel per topic, fully qualified in the node's namespace (``/pose``,
  ``/feeder1/pose``: :func:`~friction_sim.io.recordwriter.qualified_topic`).
  The topics of :data:`ADVERTISED` (those of every run: the states, the mean
  velocity, events, refused commands, parameters) are advertised at start,
  so a client that is already watching subscribes before the first slip
  rather than missing it; any other topic when its first record arrives
  (that first message reaches only clients subscribed by then: none);
* schema ``pkg/msg/Type``, encoding ``ros2msg``, the full definition rosbag2
  stores (:func:`~friction_sim.io.typesupport.message_definition`);
* messages ``cdr``, the bytes a recording holds: built by
  :mod:`friction_sim.io.messages` and serialized by :func:`friction_sim.io.cdr.serialize`,
  the states written into the fixed layouts the recording's writer uses
  (:func:`~friction_sim.io.cdr.fixed_layouts`, checked against rosbags);
* log time = the record's simulation time in whole nanoseconds.

The server is the SDK's (``foxglove.start_server``) in a context of its
own, so several live views in one process never share channels.  It binds
to ``127.0.0.1`` unless told otherwise; port 0 lets the OS choose (tests).

Cost to the caller (the node's 1 kHz tick thread): :meth:`LiveView.write` never
block and never encode.  A record for topics no client subscribes to is
counted (:attr:`LiveView.skipped`) and forgotten at once, once its channels
are advertised (a dictionary look-up and a set test; the SDK's subscribe and
unsubscribe callbacks keep the set).  Anything else goes on a bounded queue;
a background thread builds, encodes and logs it, and encodes a message only
if its channel has a subscriber then (``Channel.has_sinks``).  The thread
wakes once per ``interval`` (20 ms: a display's rate) and sends everything
queued since, so the caller neither wakes it on every call nor competes
with it for the GIL a thousand times a second; a message reaches the
clients at most that much later.

Decimation, when a client cannot keep up, happens in three places, counted
or documented, none slowing the simulation:

* Commands: at most :data:`COMMANDS_PER_SECOND` a topic and second are
  served (accepted ones on their topic, refused ones on
  ``rejected_commands``); a flood beyond that is thinned, counted in
  :attr:`LiveView.thinned`.  Encoding ten thousand refusals a second would
  take the GIL from the node's tick thread (measured: 930 instead of 980
  ticks a second); the recording keeps every one.

* Our queue (``queue_size`` messages, a state is three): when it is full the
  record being offered is dropped (the newest), counted in
  :attr:`LiveView.dropped`.  Nothing queued is evicted, so a plot shows a
  gap, never reordered data; events, commands and parameter changes (few)
  may use :data:`URGENT_HEADROOM` messages beyond the capacity.
* The SDK's per-client queue (``backlog``, ``message_backlog_size``, SDK
  default 1024): when a client reads too slowly the SDK drops that client's
  oldest data message; if its control queue (advertisements, status) fills,
  the SDK disconnects the client.  These drops are the SDK's and not counted
  here.

Where each part lives: this module is the sink (the caller's side, the
queue, the background thread, the counts and what a node reads of them);
the Foxglove channels, who subscribes to them and the building and encoding
of a record's messages are :mod:`friction_sim.io.livechannels`'s; the server
and its services :mod:`friction_sim.io.liveserver`'s.

A background thread that fails does not fail silently: :attr:`LiveView.error`
holds one line, it is logged once and sent to the clients as an error status,
and later records are refused (counted in :attr:`LiveView.dropped`).
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections import deque
from collections.abc import Sequence
from typing import Any

import foxglove

from friction_sim.errors import LiveViewError, one_line
from friction_sim.io.livechannels import LiveChannels, Subscriptions
from friction_sim.io.liveserver import (
    LiveService,
    check_address,
    check_port,
    sdk_service,
    start_server,
    wait_until_free,
)
from friction_sim.io.messages import STATE_TOPICS, TOPIC_TYPES, node_name
from friction_sim.io.sinks import CommandRecord, EventRecord, ParametersRecord, Record, record_size

_log = logging.getLogger("friction_sim.io.live")

#: Commands (accepted or refused) served per topic and second at most; more are thinned (counted).
COMMANDS_PER_SECOND = 100
#: Messages an event, command or parameter change may queue beyond the capacity.
URGENT_HEADROOM = 1024
#: The records that may use URGENT_HEADROOM (few, and a viewer would miss each one lost).
_URGENT = frozenset({EventRecord, CommandRecord, ParametersRecord})
#: Topics advertised at start (relative names; see the module docstring).
ADVERTISED = (*STATE_TOPICS, "mean_velocity", "events", "rejected_commands", "parameters")


class LiveView:
    """Serves a run to Foxglove clients while it runs (see the module docstring); a Sink.

    >>> view = LiveView(8765, namespace="/feeder1")    # doctest: +SKIP
    >>> view.url                                         # doctest: +SKIP
    'ws://127.0.0.1:8765'

    ``port`` 0 lets the OS choose (:attr:`port` says which).  ``namespace``
    qualifies relative topic names; ``node`` is the fully qualified name
    the parameter events name (default: ``slider`` in ``namespace``); ``advertise`` names the topics
    advertised at start: names of :data:`~friction_sim.io.messages.TOPIC_TYPES`,
    or (topic, ``pkg/msg/Type``) pairs for others (``("/clock",
    "rosgraph_msgs/msg/Clock")``).
    ``queue_size`` bounds our queue in messages; ``backlog`` is the SDK's
    per-client queue; the thread sends what was queued every ``interval``
    seconds (or when the queue is half full).  A port that is
    taken or an address that is not this machine's raises
    :class:`~friction_sim.errors.LiveViewError` (field ``foxglove_port`` or
    ``foxglove_address``) and leaves nothing running.  Every method is
    thread-safe and never blocks; :meth:`close` is idempotent.
    """

    #: :func:`~friction_sim.io.sinks.deliver_tick` hands this sink the state
    #: each tick published (publish_rate), not the recording's log grid.
    published_states = True

    def __init__(self, port: int = 8765, address: str = "127.0.0.1", *, namespace: str = "/", node: str | None = None,
                 advertise: Sequence[str | tuple[str, str]] = ADVERTISED, queue_size: int = 4096, backlog: int = 4096,
                 interval: float = 0.02, name: str = "friction_sim", services: Sequence[LiveService] = ()) -> None:
        check_port(port)
        check_address(address)
        if not (isinstance(namespace, str) and namespace.startswith("/")):
            raise LiveViewError("namespace", namespace, "must be an absolute ROS namespace such as / or /feeder1")
        if not (isinstance(queue_size, int) and queue_size >= 1):
            raise LiveViewError("queue_size", queue_size, "must be >= 1 message")
        if not 0.0 <= interval <= 1.0:
            raise LiveViewError("interval", interval, "must be in 0..1 s")
        unknown = [topic for topic in advertise if isinstance(topic, str) and topic not in TOPIC_TYPES]
        if unknown:
            raise LiveViewError("advertise", unknown, f"not topics of a recording: {sorted(TOPIC_TYPES)} "
                                "(give others as (topic, type) pairs)")
        self.address = address
        self.namespace = namespace
        self.node = node or node_name(namespace)
        self._capacity = queue_size
        self._interval = float(interval)
        self._lock = threading.Lock()
        self._wake = threading.Condition(self._lock)
        self._items: deque[tuple[Record, int]] = deque()
        self._pending = 0
        self._stopping = False
        self._closed = False
        self._close_lock = threading.Lock()
        self._error: str | None = None
        self._counts = {"skipped": 0, "dropped": 0, "bad": 0, "encoded": 0, "sent": 0, "thinned": 0}
        self._command_windows: dict[str, tuple[float, int]] = {}  # topic -> (window start, commands served)
        self._subscriptions = Subscriptions()
        context = foxglove.Context()
        self._server = start_server(context, name, address, port, backlog, self._subscriptions,
                                    [sdk_service(service) for service in services])
        self._port = self._server.port
        try:
            self._channels = LiveChannels(context, namespace, self.node, self._lock, self._counts, self.url)
            for topic, type_name in ((e, TOPIC_TYPES[e]) if isinstance(e, str) else e for e in advertise):
                self._channels.channel(self._channels.topic(topic), type_name)
        except BaseException:
            self._server.stop()  # leave nothing running
            raise
        self._thread = threading.Thread(target=self._run, name="foxglove_live_view", daemon=True)
        self._thread.start()

    # -- the caller's side: the sink ---------------------------------------------------

    def write(self, record: Record) -> bool:
        """Offer a sink record (:mod:`friction_sim.io.sinks`) on its topics: the
        states as pose, velocity and friction_force, each event, period mean,
        accelerometer sample, command (accepted on its own topic, ``sim_control``
        for pause, resume, step, reset; refused on ``rejected_commands``: at most
        :data:`COMMANDS_PER_SECOND` a topic, a flood is thinned, counted),
        parameter set, /clock and any other message (diagnostics, target_speed)
        at its own simulation time.  Built and encoded later, on the background
        thread, and only if a client subscribes to one of its topics (or it has
        no channel yet); else counted skipped.  False if it was dropped (queue
        full, failed or closed; counted)."""
        size = record_size(record)
        if not size:
            return True
        topics = self._channels.qualified(record)
        if not self._wanted(topics, size):
            return True
        kind = type(record)
        if kind is CommandRecord and self._thinned(topics[0]):
            return True
        return self._put(record, size, urgent=kind in _URGENT)

    def close(self) -> None:
        """Stop the thread and the server (the port is free when it returns);
        records still queued are counted as dropped.  Idempotent, thread-safe."""
        with self._close_lock:
            if self._closed:
                return
            with self._lock:
                self._stopping = True
                self._wake.notify_all()
            self._thread.join(timeout=10.0)
            if self._thread.is_alive():
                _log.warning("live view %s: the background thread did not end within 10 s", self.url)
            with self._lock:
                self._counts["dropped"] += self._pending
                self._items.clear()
                self._pending = 0
            self._channels.close()
            self._server.stop()
            wait_until_free(self.address, self._port)
            self._closed = True

    def __enter__(self) -> LiveView:
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    # -- state for diagnostics -----------------------------------------------------------

    @property
    def url(self) -> str:
        """Where clients connect: ``ws://address:port``."""
        host = f"[{self.address}]" if ":" in self.address else self.address
        return f"ws://{host}:{self._port}"

    @property
    def port(self) -> int:
        """The TCP port the server listens on (the OS's choice for port 0)."""
        return self._port

    @property
    def clients(self) -> int:
        """Clients subscribed to at least one channel (the SDK tells of
        subscriptions, not of connections: a client that subscribes to
        nothing is not counted)."""
        return self._subscriptions.clients

    @property
    def sent(self) -> int:
        """Messages handed to the server (to every subscribed client)."""
        return self._counts["sent"]

    @property
    def encoded(self) -> int:
        """Messages serialized to CDR (only for channels with a subscriber)."""
        return self._counts["encoded"]

    @property
    def thinned(self) -> int:
        """Commands not served because their topic had COMMANDS_PER_SECOND this second."""
        return self._counts["thinned"]

    @property
    def skipped(self) -> int:
        """Messages not built because no client subscribed to their topic."""
        return self._counts["skipped"]

    @property
    def dropped(self) -> int:
        """Messages lost: our queue was full, the view had failed or was
        closed, or no message could hold the record (a topic reused with
        another type, a time no ROS stamp holds)."""
        return self._counts["dropped"] + self._counts["bad"]

    @property
    def error(self) -> str | None:
        """Why the live view stopped serving (one line), or None while it works."""
        return self._error

    def stats(self) -> dict[str, Any]:
        """The figures a node merges into its diagnostics (error "" while it works)."""
        return {"live_view_url": self.url, "live_view_clients": self.clients, "live_view_sent": self.sent,
                "live_view_dropped": self.dropped, "live_view_thinned": self.thinned,
                "live_view_error": self._error or ""}

    # -- the caller's side: queueing ---------------------------------------------------

    def _wanted(self, topics: tuple[str, ...], size: int) -> bool:
        """Whether a record for ``topics`` must be queued: some client
        subscribes to one of them, or one is not advertised yet (its first
        record makes the channel).  Otherwise count it as skipped."""
        if self._subscriptions.live.isdisjoint(topics) and self._channels.advertised.issuperset(topics):
            with self._lock:
                self._counts["skipped"] += size
            return False
        return True

    def _thinned(self, topic: str) -> bool:
        """Whether a command on ``topic`` is one too many this second (counted):
        a flood of thousands a second would cost the simulation's process the
        encoding of each; a viewer sees at most COMMANDS_PER_SECOND of them
        (the recording keeps them all)."""
        now = time.monotonic()
        with self._lock:
            start, served = self._command_windows.get(topic, (now, 0))
            if now - start >= 1.0:
                start, served = now, 0
            if served >= COMMANDS_PER_SECOND:
                self._counts["thinned"] += 1
                return True
            self._command_windows[topic] = (start, served + 1)
            return False

    def _put(self, item: Record, size: int, *, urgent: bool = False) -> bool:
        """Queue ``item`` (``size`` messages) unless the queue is full, the view
        failed or is closing (then count it dropped); never waits."""
        with self._lock:
            capacity = self._capacity + (URGENT_HEADROOM if urgent else 0)
            if self._stopping or self._error is not None or (self._pending and self._pending + size > capacity):
                self._counts["dropped"] += size
                return False
            self._items.append((item, size))
            self._pending += size
            if len(self._items) == 1 or self._capacity // 2 <= self._pending < self._capacity // 2 + size:
                self._wake.notify()  # the first of a batch, or half full: not every call (a futex wake costs)
            return True

    # -- the background thread -------------------------------------------------------------

    def _run(self) -> None:
        """Take records off the queue and serve them until closed; a failure is
        recorded in :attr:`error`, logged once and shown to the clients."""
        batch: list[tuple[Record, int]] = []
        served = 0
        try:
            while True:
                with self._lock:
                    while not self._items and not self._stopping:
                        self._wake.wait()
                    if not self._stopping and self._pending < self._capacity // 2:
                        self._wake.wait(self._interval)  # gather: one wake-up (and GIL hand-over) a batch
                    if self._stopping:
                        return
                    batch, served = list(self._items), 0
                    self._items.clear()
                    self._pending = 0
                for item, size in batch:
                    self._channels.serve(item, size)
                    served += 1
        except BaseException as error:  # noqa: BLE001 - a dying thread must say why (then it ends)
            self._fail(error, sum(size for _, size in batch[served:]))

    def _fail(self, error: BaseException, unserved: int) -> None:
        """Record why the thread stopped (``unserved`` messages taken but not
        served are counted dropped), refuse later records, tell the log and the clients."""
        text = f"live view stopped: {one_line(error, with_type=True)}"
        with self._lock:
            self._error = text
            self._counts["dropped"] += self._pending + unserved
            self._items.clear()
            self._pending = 0
        _log.error("%s (%s)", text, self.url)
        with contextlib.suppress(Exception):  # a courtesy to the clients; the error is already recorded
            self._server.publish_status(text, foxglove.StatusLevel.Error)


__all__ = ["ADVERTISED", "COMMANDS_PER_SECOND", "URGENT_HEADROOM", "LiveService", "LiveView"]
