"""--foxglove: the recorder's live sink serves each topic to a Foxglove client.

A client here speaks the Foxglove WebSocket protocol over a raw socket: it must see the
topic advertised with its ROS 2 schema and, once subscribed, receive the CDR bytes the
recorder took from DDS, unchanged.
"""

from __future__ import annotations

import base64
import json
import os
import socket
import struct

import pytest
from ament_index_python.packages import get_package_share_directory
from rclpy.serialization import serialize_message
from std_msgs.msg import String

from dombot_bringup.recording import FoxgloveSink, message_definition

MESSAGE_DATA = 1  # server → client binary opcode


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


class Client:
    """Just enough of a WebSocket client for the Foxglove protocol's first messages."""

    def __init__(self, port: int) -> None:
        self.socket = socket.create_connection(("127.0.0.1", port), timeout=30)
        key = base64.b64encode(os.urandom(16)).decode()
        self.socket.sendall(
            (
                f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n"
                f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
                "Sec-WebSocket-Version: 13\r\n"
                "Sec-WebSocket-Protocol: foxglove.sdk.v1, foxglove.websocket.v1\r\n\r\n"
            ).encode()
        )
        response = b""
        while b"\r\n\r\n" not in response:
            response += self.socket.recv(1)
        assert b" 101 " in response.split(b"\r\n")[0], response

    def _exactly(self, size: int) -> bytes:
        data = b""
        while len(data) < size:
            chunk = self.socket.recv(size - len(data))
            assert chunk, "the server closed the connection"
            data += chunk
        return data

    def receive(self) -> tuple[int, bytes]:
        first, second = self._exactly(2)
        size = second & 0x7F
        if size == 126:
            size = struct.unpack(">H", self._exactly(2))[0]
        elif size == 127:
            size = struct.unpack(">Q", self._exactly(8))[0]
        return first & 0x0F, self._exactly(size)

    def send_json(self, content: dict) -> None:
        payload, mask = json.dumps(content).encode(), os.urandom(4)
        assert len(payload) < 126
        masked = bytes(byte ^ mask[i % 4] for i, byte in enumerate(payload))
        self.socket.sendall(bytes([0x81, 0x80 | len(payload)]) + mask + masked)

    def next_json(self, op: str) -> dict:
        for _ in range(20):
            opcode, payload = self.receive()
            if opcode == 1 and json.loads(payload).get("op") == op:
                return json.loads(payload)
        raise AssertionError(f"no '{op}' message")


@pytest.fixture
def sink():
    sink = FoxgloveSink(port=free_port())
    yield sink
    sink.close()


def test_a_recorded_topic_reaches_a_foxglove_client_unchanged(sink: FoxgloveSink) -> None:
    definition = message_definition("std_msgs/msg/String", get_package_share_directory)
    sink.add_channel("/chatter", "std_msgs/msg/String", definition, {})
    client = Client(int(sink.url.rsplit(":", 1)[1]))
    channels = client.next_json("advertise")["channels"]
    [chatter] = [c for c in channels if c["topic"] == "/chatter"]
    assert chatter["schemaName"] == "std_msgs/msg/String"
    assert chatter["encoding"] == "cdr" and chatter["schemaEncoding"] == "ros2msg"
    assert chatter["schema"] == definition

    client.send_json({"op": "subscribe", "subscriptions": [{"id": 7, "channelId": chatter["id"]}]})
    data = serialize_message(String(data="a domino fell"))
    for _ in range(300):  # until the subscription has arrived at the server
        sink.write("/chatter", data, log_time=123, publish_time=123)
        client.socket.settimeout(0.2)
        try:
            opcode, payload = client.receive()
        except TimeoutError:
            continue
        if opcode == 2 and payload[0] == MESSAGE_DATA:
            break
    else:
        raise AssertionError("no message reached the client")
    subscription, log_time = struct.unpack("<IQ", payload[1:13])
    assert (subscription, log_time) == (7, 123)
    assert payload[13:] == data
