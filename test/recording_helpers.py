"""Helpers shared by the recording tests (test/io, test/ros): the replay
subcommand's arguments, copying a recording, and messages as plain values."""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from friction_sim.core.model.commands import Command
from friction_sim.core.runtime.simulation import random_schedule
from friction_sim.io.reader import read_recording
from friction_sim.io.recorder import METADATA_NAME, Recorder
from friction_sim.io.sinks import MessageRecord


def replay_args(path: Path, **options: Any) -> argparse.Namespace:
    """The parsed options of ``friction-sim replay path`` with ``options`` set."""
    defaults = dict(file=path, verify=False, tolerance=1e-9, publish=False, rate=1.0, loop=False, topics=None,
                    namespace="", delay=0.0, csv=None, plot=None)
    defaults.update(options)
    return argparse.Namespace(**defaults)


def rewrite(source: Path, target: Path, edit: Callable[[str, int, Any], Any] = lambda topic, t, msg: msg,
            *, metadata: Callable[[dict[str, str]], dict[str, str]] = lambda data: data,
            **recorder_options: Any) -> Path:
    """Copy a recording message by message; ``edit`` may change a message or
    drop it (None); ``metadata`` may change the friction_sim metadata record."""
    recording = read_recording(source)
    with Recorder(target, metadata=metadata(dict(recording.metadata[METADATA_NAME])), **recorder_options) as out:
        for raw in recording.messages:
            msg = edit(raw.topic, raw.log_time, recording.decode(raw))
            if msg is not None:
                out.write(MessageRecord(raw.topic, msg, raw.log_time))
    return target


def plain(value: Any) -> Any:
    """rclpy and rosbags messages as comparable plain Python values."""
    if hasattr(value, "get_fields_and_field_types"):
        return {name: plain(getattr(value, name)) for name in value.get_fields_and_field_types()}
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: plain(getattr(value, f.name)) for f in dataclasses.fields(value)
                if f.name != "__msgtype__" and not f.name.isupper()}  # constants are not fields
    if isinstance(value, bytes):
        return value[0] if len(value) == 1 else list(value)
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (list, tuple, np.ndarray)) or type(value).__name__ == "array":
        return [plain(v) for v in value]
    return value


def varied_schedule() -> list[Command]:
    """1.5 s of random commands with external forces, a refused command and a plant change."""
    schedule = random_schedule(np.random.default_rng(7), 1.5, external=True)
    schedule.append(Command(0.5, "excitation_amplitude", {"excitation_amplitude": -1.0}))  # refused: Pa < 0
    schedule.append(Command(0.8, "parameters", {"mass": 1.2, "mu": 0.12}))  # a plant change, as ros2 param set
    return schedule


def copy_recording(source: Path, target: Path, *, chunk_size: int = 4 * 1024 * 1024,
                   topic: Callable[[str], str] = lambda name: name,
                   keep: Callable[[str, int], bool] = lambda name, log_time: True,
                   metadata: dict[str, dict[str, str]] | None = None, without: tuple[str, ...] = ()) -> Path:
    """Copy a recording record by record with mcap alone (no friction_sim
    reader): chunks of ``chunk_size`` bytes, topics renamed by ``topic``,
    only the messages ``keep(topic, log time)`` accepts, metadata records
    replaced or added by ``metadata``, those named in ``without`` left out.
    Serialized messages are copied as
    they are."""
    from mcap.reader import make_reader
    from mcap.writer import CompressionType, Writer

    with source.open("rb") as stream, target.open("wb") as out:
        reader = make_reader(stream)
        summary = reader.get_summary()
        assert summary is not None
        header = reader.get_header()
        writer = Writer(out, chunk_size=chunk_size, compression=CompressionType.ZSTD)
        writer.start(profile=header.profile, library=header.library)
        records = {record.name: dict(record.metadata) for record in reader.iter_metadata()}
        for name, data in {**records, **(metadata or {})}.items():
            if name not in without:
                writer.add_metadata(name, data)
        schemas = {sid: writer.register_schema(s.name, s.encoding, s.data) for sid, s in summary.schemas.items()}
        channels = {cid: writer.register_channel(topic(c.topic), c.message_encoding, schemas[c.schema_id],
                                                 dict(c.metadata)) for cid, c in summary.channels.items()}
        for _, channel, message in reader.iter_messages(log_time_order=False):
            if keep(channel.topic, message.log_time):
                writer.add_message(channels[channel.id], message.log_time, message.data, message.publish_time,
                                   message.sequence)
        writer.finish()
    return target
