"""A Foxglove WebSocket client for tests, independent of the server library.

Speaks the protocol the Foxglove SDK serves (subprotocol ``foxglove.sdk.v1``;
foxglove-sdk 0.30 refuses the legacy ``foxglove.websocket.v1``), as its
published spec (foxglove/ws-protocol ``docs/spec.md``) describes it:

* text frames are JSON with an ``op``: the server sends ``serverInfo`` first,
  then ``advertise`` (``channels``: id, topic, encoding, schemaName,
  schemaEncoding, schema), ``unadvertise`` (``channelIds``) and ``status``;
  the client sends ``subscribe`` (``subscriptions``: id, channelId) and
  ``unsubscribe`` (``subscriptionIds``);
* binary frames start with an opcode byte; ``1`` is message data: uint32
  subscription id, uint64 log time [ns] (little endian), then the payload.

The WebSocket is the ``websockets`` package's (sync client); payloads are
decoded from the advertised ``ros2msg`` schema text by mcap-ros2-support's
decoder, not by friction_sim's code, so a test compares what a real client
sees with what was handed to the server.

>>> with FoxgloveClient("ws://127.0.0.1:8765") as client:    # doctest: +SKIP
...     client.subscribe("/pose")
...     received = client.collect(until=lambda got: len(got) >= 10)
"""

from __future__ import annotations

import json
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass
from types import TracebackType
from typing import Any

from mcap.records import Schema
from mcap_ros2.decoder import DecoderFactory
from websockets.sync.client import ClientConnection, connect

SUBPROTOCOL = "foxglove.sdk.v1"
#: Binary opcode of a message data frame (server to client).
MESSAGE_DATA = 1
_HEADER = struct.Struct("<BIQ")  # opcode, subscription id, log time [ns]
#: Binary opcodes of a service call: request (client to server) and response (server to client).
SERVICE_CALL_REQUEST, SERVICE_CALL_RESPONSE = 2, 3
_SERVICE_HEADER = struct.Struct("<BIII")  # opcode, service id, call id, encoding length (then encoding, payload)


@dataclass(frozen=True)
class Received:
    """One message a subscription delivered: its topic, log time and decoded message."""

    topic: str
    log_time_ns: int
    message: Any
    payload: bytes


class FoxgloveClient:
    """A connection to a Foxglove WebSocket server (a context manager).

    :attr:`server_info` is the server's ``serverInfo``; :attr:`channels`
    maps each advertised topic to its channel (the advertised JSON object);
    :attr:`statuses` collects ``status`` messages.  Every read keeps these
    up to date."""

    def __init__(self, url: str, *, timeout: float = 5.0) -> None:
        self.url = url
        self.timeout = timeout
        self.server_info: dict[str, Any] = {}
        self.channels: dict[str, dict[str, Any]] = {}
        self.statuses: list[dict[str, Any]] = []
        self.services: dict[str, dict[str, Any]] = {}
        self._responses: dict[int, bytes | Exception] = {}
        self._ws: ClientConnection | None = None
        self._subscriptions: dict[int, str] = {}  # subscription id -> topic
        self._by_topic: dict[str, int] = {}
        self._next_id = 1
        self._decoders = DecoderFactory()

    def __enter__(self) -> FoxgloveClient:
        # close_timeout: a server with a backlog of data for us may answer the closing handshake late
        self._ws = connect(self.url, subprotocols=[SUBPROTOCOL], open_timeout=self.timeout, max_size=None,
                           close_timeout=0.5)
        self._ws.__enter__()  # (websockets wants its connection used as a context manager)
        if self._ws.subprotocol != SUBPROTOCOL:
            raise AssertionError(f"server chose subprotocol {self._ws.subprotocol!r}")
        while not self.server_info:
            self._read(self.timeout)
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 traceback: TracebackType | None) -> None:
        self.close()

    def close(self) -> None:
        """Close the connection (idempotent)."""
        if self._ws is not None:
            self._ws.close()
            self._ws = None

    @property
    def ws(self) -> ClientConnection:
        """The open WebSocket (for tests that send raw frames)."""
        if self._ws is None:
            raise RuntimeError("the client is not connected")
        return self._ws

    # -- channels and subscriptions ----------------------------------------------------

    def wait_for_channels(self, *topics: str, timeout: float | None = None) -> dict[str, dict[str, Any]]:
        """The channels of ``topics``, reading until each is advertised
        (TimeoutError naming the missing ones)."""
        deadline = time.monotonic() + (self.timeout if timeout is None else timeout)
        while missing := [topic for topic in topics if topic not in self.channels]:
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError(f"not advertised within the timeout: {missing}; advertised: {sorted(self.channels)}")
            self._read(left)
        return {topic: self.channels[topic] for topic in topics}

    def subscribe(self, *topics: str) -> None:
        """Subscribe to ``topics`` (waiting for their advertisement), one subscription id each."""
        subscriptions = []
        for topic, channel in self.wait_for_channels(*topics).items():
            subscription = self._next_id
            self._next_id += 1
            self._subscriptions[subscription] = topic
            self._by_topic[topic] = subscription
            subscriptions.append({"id": subscription, "channelId": channel["id"]})
        self.ws.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))

    def unsubscribe(self, *topics: str) -> None:
        """End the subscriptions of ``topics``."""
        ids = [self._by_topic.pop(topic) for topic in topics]
        for subscription in ids:
            self._subscriptions.pop(subscription, None)
        self.ws.send(json.dumps({"op": "unsubscribe", "subscriptionIds": ids}))

    # -- receiving ---------------------------------------------------------------------

    def collect(self, seconds: float | None = None, *, until: Callable[[list[Received]], bool] | None = None,
                timeout: float | None = None) -> list[Received]:
        """Messages received for ``seconds``, or until ``until(received)`` is
        true (at most ``timeout``, default the client's: then what came)."""
        limit = seconds if seconds is not None else (self.timeout if timeout is None else timeout)
        deadline = time.monotonic() + limit
        received: list[Received] = []
        while until is None or not until(received):
            left = deadline - time.monotonic()
            if left <= 0:
                break
            message = self._read(left)
            if message is not None:
                received.append(message)
        return received

    def _read(self, timeout: float) -> Received | None:
        """Read one frame: a data message is returned decoded, anything else
        updates the client's state (None; None also when nothing came in time)."""
        try:
            frame = self.ws.recv(timeout=timeout)
        except TimeoutError:
            return None
        if isinstance(frame, str):
            self._control(json.loads(frame))
            return None
        if frame[0] == SERVICE_CALL_RESPONSE:
            _, _, call, length = _SERVICE_HEADER.unpack_from(frame)
            self._responses[call] = bytes(frame[_SERVICE_HEADER.size + length:])
            return None
        if frame[0] != MESSAGE_DATA:
            return None  # time frames: not used here
        _, subscription, log_time, = _HEADER.unpack_from(frame)
        payload = bytes(frame[_HEADER.size:])
        topic = self._subscriptions.get(subscription)
        if topic is None:
            return None  # a message already on its way when we unsubscribed
        return Received(topic, log_time, self._decode(self.channels[topic], payload), payload)

    def _control(self, message: dict[str, Any]) -> None:
        """Apply a JSON control message."""
        op = message.get("op")
        if op == "serverInfo":
            self.server_info = message
        elif op == "advertise":
            for channel in message["channels"]:
                self.channels[channel["topic"]] = channel
        elif op == "unadvertise":
            gone = set(message["channelIds"])
            self.channels = {topic: ch for topic, ch in self.channels.items() if ch["id"] not in gone}
        elif op == "status":
            self.statuses.append(message)
        elif op == "advertiseServices":
            for service in message["services"]:
                self.services[service["name"]] = service
        elif op == "serviceCallFailure":
            self._responses[message["callId"]] = RuntimeError(message.get("message", "service call failed"))

    # -- services ------------------------------------------------------------------------

    def call_service(self, name: str, payload: bytes = b"", timeout: float | None = None) -> Any:
        """Call service ``name`` (waiting for its advertisement) with the CDR
        ``payload``; the response decoded from its advertised schema
        (RuntimeError with the server's reason if the call failed)."""
        deadline = time.monotonic() + (self.timeout if timeout is None else timeout)
        while name not in self.services:
            if time.monotonic() > deadline:
                raise TimeoutError(f"service {name} not advertised; advertised: {sorted(self.services)}")
            self._read(0.1)
        service = self.services[name]
        call, self._next_id = self._next_id, self._next_id + 1
        encoding = b"cdr"
        header = _SERVICE_HEADER.pack(SERVICE_CALL_REQUEST, service["id"], call, len(encoding))
        self.ws.send(header + encoding + payload)
        while call not in self._responses:
            if time.monotonic() > deadline:
                raise TimeoutError(f"no answer from service {name}")
            self._read(0.1)
        answer = self._responses.pop(call)
        if isinstance(answer, Exception):
            raise answer
        response = service.get("response") or {"encoding": "cdr", "schemaName": service["type"] + "_Response",
                                               "schemaEncoding": "ros2msg", "schema": service["responseSchema"]}
        schema = Schema(id=service["id"], name=response["schemaName"], encoding=response["schemaEncoding"],
                        data=response["schema"].encode("utf-8"))
        decoder = self._decoders.decoder_for(response["encoding"], schema)
        assert decoder is not None, response
        return decoder(answer)

    def _decode(self, channel: dict[str, Any], payload: bytes) -> Any:
        """The message in ``payload``, decoded from the channel's schema text
        by mcap-ros2-support (None for an encoding it does not read)."""
        schema = Schema(id=channel["id"], name=channel["schemaName"], encoding=channel.get("schemaEncoding", ""),
                        data=channel["schema"].encode("utf-8"))
        decoder = self._decoders.decoder_for(channel["encoding"], schema)
        return decoder(payload) if decoder is not None else None


__all__ = ["MESSAGE_DATA", "SERVICE_CALL_REQUEST", "SERVICE_CALL_RESPONSE", "SUBPROTOCOL", "FoxgloveClient", "Received"]
