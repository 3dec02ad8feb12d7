"""Recording ROS 2 topics to MCAP and reading them back, without ROS.

What rosbag2's MCAP storage does, in the pieces a recorder and a player need:

* ``message_definition``: a type's complete definition in rosbag2's ``ros2msg`` form
  (its .msg text, then every type it uses, each after a line of 80 ``=`` and
  ``MSG: pkg/msg/Type``), the schema Foxglove and ``mcap_ros2`` decode messages with;
* ``McapSink``: raw CDR messages as they came off the wire, one channel per topic;
* ``Throttle``, ``header_stamp``: raw images thinned to a rate by their stamps (a run's
  full-rate cameras are GBs);
* ``recorded_messages``: a file's messages in log-time order, for a player.
"""

from __future__ import annotations

import re
import struct
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO, Protocol

from mcap.reader import make_reader
from mcap.well_known import MessageEncoding, SchemaEncoding
from mcap.writer import CompressionType, Writer

SEPARATOR = "=" * 80
PRIMITIVES = frozenset(
    {"bool", "byte", "char", "float32", "float64", "string", "wstring"}
    | {f"{sign}int{bits}" for sign in ("", "u") for bits in (8, 16, 32, 64)}
)
THROTTLED_TYPES = frozenset({"sensor_msgs/msg/Image"})  # raw images; compressed ones go in full
# metadata keys of each channel: the publishers' QoS, for a player to offer the same
DURABILITY, RELIABILITY = "durability", "reliability"
TRANSIENT_LOCAL, VOLATILE = "transient_local", "volatile"
RELIABLE, BEST_EFFORT = "reliable", "best_effort"

ShareDir = Callable[[str], Path]  # package name -> its share folder (the ament index)


class DefinitionNotFoundError(LookupError):
    """A type (or a type it uses) has no .msg file in its package's share folder."""


def _field_types(text: str) -> Iterator[str]:
    """The type of each field and constant of a .msg text, array bounds stripped."""
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            yield re.split(r"[\[<]", line.split()[0], maxsplit=1)[0]


def _full_name(field_type: str, package: str) -> str | None:
    """'pkg/Type', 'pkg/msg/Type' or 'Type' (same package) as 'pkg/msg/Type'; None for
    primitives."""
    if field_type in PRIMITIVES:
        return None
    parts = field_type.split("/")
    return f"{package}/msg/{parts[0]}" if len(parts) == 1 else f"{parts[0]}/msg/{parts[-1]}"


def message_definition(type_name: str, share_dir: ShareDir) -> str:
    """The complete ``ros2msg`` definition of ``type_name`` ('pkg/msg/Type'), as rosbag2
    writes it into an MCAP schema."""
    texts: dict[str, str] = {}
    pending = [type_name]
    while pending:
        name = pending.pop(0)
        if name in texts:
            continue
        package, _, short = name.split("/")
        try:
            path = Path(share_dir(package)) / "msg" / f"{short}.msg"
            texts[name] = path.read_text()
        except (OSError, LookupError, ValueError) as error:
            raise DefinitionNotFoundError(f"no definition of {name}: {error}") from None
        used = (_full_name(t, package) for t in _field_types(texts[name]))
        pending.extend(u for u in used if u is not None and u not in texts)
    root, *others = texts
    return f"{texts[root].rstrip()}\n" + "".join(
        f"{SEPARATOR}\nMSG: {name}\n{texts[name].rstrip()}\n" for name in others
    )


def header_stamp(data: bytes) -> int | None:
    """The header stamp [ns] of a CDR message whose first field is a ``std_msgs/Header``
    (images, camera infos), read without decoding the rest; None if too short."""
    if len(data) < 12:
        return None
    order = "<" if data[1] & 1 else ">"  # encapsulation: CDR_LE or CDR_BE
    sec, nanosec = struct.unpack_from(f"{order}iI", data, 4)
    return sec * 10**9 + nanosec


class Throttle:
    """Keeps at most one message of a topic per period (0 Hz: none) of the times given:
    the messages' stamps, which are exact where receive times jitter (2 Hz frames thinned
    to 1 Hz by receive time kept two in three seconds)."""

    def __init__(self, rate_hz: float) -> None:
        if not rate_hz >= 0.0:
            raise ValueError(f"a rate must be >= 0 Hz, got {rate_hz}")
        self._period = None if rate_hz == 0.0 else round(1e9 / rate_hz)
        self._last: dict[str, int] = {}

    def keep(self, topic: str, log_time: int) -> bool:
        if self._period is None:
            return False
        last = self._last.get(topic)
        if last is not None and 0 <= log_time - last < self._period:
            return False
        self._last[topic] = log_time
        return True


class Sink(Protocol):
    """Where a recorder sends messages: an MCAP file, a live Foxglove server."""

    def add_channel(self, topic: str, type_name: str, definition: str, qos: dict) -> None: ...
    def write(self, topic: str, data: bytes, log_time: int, publish_time: int) -> None: ...
    def close(self) -> None: ...


class McapSink:
    """Raw CDR messages to an MCAP file with ``ros2msg`` schemas (profile ``ros2``)."""

    def __init__(self, path: Path) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        self._stream: BinaryIO = open(path, "wb")  # noqa: SIM115 (closed in close())
        self._writer = Writer(self._stream, compression=CompressionType.ZSTD)
        self._writer.start(profile="ros2", library="dombot_bringup recorder")
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._sequence = 0
        self.counts: dict[str, int] = {}

    def add_channel(self, topic: str, type_name: str, definition: str, qos: dict) -> None:
        if type_name not in self._schemas:
            self._schemas[type_name] = self._writer.register_schema(
                type_name, SchemaEncoding.ROS2, definition.encode()
            )
        self._channels[topic] = self._writer.register_channel(
            topic, MessageEncoding.CDR, self._schemas[type_name], metadata=qos
        )
        self.counts[topic] = 0

    def write(self, topic: str, data: bytes, log_time: int, publish_time: int) -> None:
        self._sequence += 1
        self._writer.add_message(
            self._channels[topic], log_time, data, publish_time, sequence=self._sequence
        )
        self.counts[topic] += 1

    def close(self) -> None:
        if not self._stream.closed:
            self._writer.finish()
            self._stream.close()


@dataclass(frozen=True)
class RecordedMessage:
    topic: str
    type_name: str
    data: bytes  # CDR, as published
    log_time: int  # ns


def recorded_messages(path: Path) -> Iterator[RecordedMessage]:
    """Every message of an MCAP file, in log-time order."""
    with open(path, "rb") as stream:
        reader = make_reader(stream)
        for schema, channel, message in reader.iter_messages(log_time_order=True):
            yield RecordedMessage(
                topic=channel.topic,
                type_name=schema.name if schema is not None else "",
                data=message.data,
                log_time=message.log_time,
            )


def recorded_channels(path: Path) -> dict[str, tuple[str, dict[str, str]]]:
    """Topic -> (type name, metadata) of each channel in an MCAP file (from its summary)."""
    with open(path, "rb") as stream:
        summary = make_reader(stream).get_summary()
    if summary is None:
        return {}
    return {
        channel.topic: (summary.schemas[channel.schema_id].name, dict(channel.metadata))
        for channel in summary.channels.values()
        if channel.schema_id in summary.schemas
    }


FOXGLOVE_MISSING = (
    "--foxglove needs the Foxglove SDK, which is not installed: "
    "pip install foxglove-sdk (into this venv: .venv/bin/pip install foxglove-sdk)"
)


class FoxgloveSink:
    """The same messages, live, to a Foxglove WebSocket server (``foxglove-sdk``); open
    ``ws://HOST:PORT`` in the Foxglove app."""

    def __init__(self, host: str = "127.0.0.1", port: int = 8765) -> None:
        try:
            import foxglove
        except ImportError:
            raise RuntimeError(FOXGLOVE_MISSING) from None
        self._foxglove = foxglove
        self._server = foxglove.start_server(name="dombot", host=host, port=port)
        self._channels: dict[str, object] = {}
        self.url = f"ws://{host}:{port}"

    def add_channel(self, topic: str, type_name: str, definition: str, qos: dict) -> None:
        schema = self._foxglove.Schema(
            name=type_name, encoding=SchemaEncoding.ROS2, data=definition.encode()
        )
        self._channels[topic] = self._foxglove.Channel(
            topic, schema=schema, message_encoding=MessageEncoding.CDR
        )

    def write(self, topic: str, data: bytes, log_time: int, publish_time: int) -> None:
        self._channels[topic].log(data, log_time=log_time)

    def close(self) -> None:
        self._server.stop()


def foxglove_available() -> bool:
    """Is the Foxglove SDK importable (``pip install foxglove-sdk``)?"""
    import importlib.util

    return importlib.util.find_spec("foxglove") is not None
