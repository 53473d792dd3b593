"""The live view's server side: the Foxglove SDK's WebSocket server started
with the errors a user can act on, and services offered to its clients.

:func:`start_server` maps the SDK's failures to one
:class:`~friction_sim.errors.LiveViewError` naming ``foxglove_port`` or
``foxglove_address``; :class:`LiveService` is a service a Foxglove client
calls (the slider's pause, resume, step and reset), with its ros2msg
request and response schemas read from the installed ``.srv`` file.
"""

from __future__ import annotations

import ipaddress
import logging
import re
import socket
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import foxglove
from foxglove.websocket import (
    Capability,
    MessageSchema,
    ServerListener,
    Service,
    ServiceRequest,
    ServiceSchema,
)

from friction_sim.errors import LiveViewError, one_line
from friction_sim.io.typesupport import service_definitions

_log = logging.getLogger("friction_sim.io.live")
_PORT_FIELD, _ADDRESS_FIELD = "foxglove_port", "foxglove_address"
_HOST_LABEL = re.compile(r"(?!-)[A-Za-z0-9-]{1,63}(?<!-)")


def check_port(port: Any) -> None:
    """``port`` must be a TCP port number (0: any free one)."""
    if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
        raise LiveViewError(_PORT_FIELD, port, "must be a TCP port in 0..65535 (0: any free port)")


def check_address(address: Any) -> None:
    """``address`` must be an IP address or a well-formed host name; checked
    here, so that text that is neither is refused without a DNS look-up."""
    if isinstance(address, str) and address:
        try:
            ipaddress.ip_address(address)
            return
        except ValueError:
            labels = address.rstrip(".").split(".")
            if len(address) <= 253 and all(_HOST_LABEL.fullmatch(label) for label in labels) \
                    and not labels[-1].isdigit():
                return
    raise LiveViewError(_ADDRESS_FIELD, address, "must be an IP address or a host name, e.g. 127.0.0.1 "
                        "(this machine only) or 0.0.0.0 (every interface)")


def wait_until_free(address: str, port: int, timeout: float = 2.0) -> None:
    """Wait until nothing listens on ``address``:``port`` (the SDK's stop
    returns before its listener is closed, about a millisecond later), so a
    new live view may take the port at once.  Host names are not looked up:
    then this returns at once."""
    try:
        family = socket.AF_INET6 if ipaddress.ip_address(address).version == 6 else socket.AF_INET
    except ValueError:
        return
    deadline = time.monotonic() + timeout
    while True:
        with socket.socket(family, socket.SOCK_STREAM) as probe:
            probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as servers bind: TIME_WAIT is no listener
            try:
                probe.bind((address, port))
                return
            except OSError:
                if time.monotonic() > deadline:
                    _log.warning("live view: port %d on %s still taken %.0f s after stop", port, address, timeout)
                    return
        time.sleep(0.001)


@dataclass(frozen=True)
class LiveService:
    """A service Foxglove clients may call through the live view (its Call
    Service panel): ``name`` fully qualified (``/slider/pause``), ``type_name``
    ``pkg/srv/Type``; ``handler`` takes the request's CDR bytes and returns
    the response's (the caller encodes them: the node with rclpy).  It runs on
    the server's thread; what it raises is sent to the client as the reason."""

    name: str
    type_name: str
    handler: Callable[[bytes], bytes]


def sdk_service(service: LiveService) -> Service:
    """``service`` as the SDK's: ros2msg request and response schemas from the
    installed .srv file, CDR both ways."""
    request, response = service_definitions(service.type_name)
    package, _, name = service.type_name.split("/")

    def schema(text: str, part: str) -> MessageSchema:
        return MessageSchema(encoding="cdr", schema=foxglove.Schema(
            name=f"{package}/srv/{name}_{part}", encoding="ros2msg", data=text.encode("utf-8")))

    def handle(request_: ServiceRequest) -> bytes:
        return service.handler(request_.payload)

    return Service(service.name, schema=ServiceSchema(service.type_name, request=schema(request, "Request"),
                                                      response=schema(response, "Response")), handler=handle)


def start_server(context: foxglove.Context, name: str, address: str, port: int, backlog: int,
                  listener: ServerListener, services: list[Service]) -> foxglove.WebSocketServer:
    """The SDK's server, or one LiveViewError naming the field to blame.

    The SDK raises RuntimeError("FoxgloveError: Failed to bind port: <reason>"):
    ``Address already in use (os error 98)`` for a port something listens
    on (another live view: choose another foxglove_port), ``Cannot assign
    requested address (os error 99)`` for an address not of this machine,
    ``failed to lookup address information`` for an unknown host name."""
    try:
        return foxglove.start_server(name=name, host=address, port=port, context=context,
                                     server_listener=listener, message_backlog_size=backlog,
                                     capabilities=[Capability.Services] if services else None,
                                     supported_encodings=["cdr"] if services else None,
                                     services=services or None)
    except (RuntimeError, OSError, ValueError, OverflowError) as error:
        reason = one_line(error).removeprefix("FoxgloveError: ").removeprefix("Failed to bind port: ")
        if "in use" in reason:
            raise LiveViewError(_PORT_FIELD, port, f"port {port} on {address} is already in use (another "
                                f"live view or program listens there; choose another port): {reason}") from None
        if "Permission denied" in reason:
            raise LiveViewError(_PORT_FIELD, port, f"not allowed to listen on port {port}: {reason}") from None
        raise LiveViewError(_ADDRESS_FIELD, address, f"cannot listen there: {reason}") from None


__all__ = ["LiveService", "check_address", "check_port", "sdk_service", "start_server", "wait_until_free"]
