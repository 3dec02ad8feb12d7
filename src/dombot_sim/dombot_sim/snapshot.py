"""snapshot: save the next colour and depth frame of each camera as PNG files.

``ros2 run dombot_sim snapshot --out DIR [--cameras camera_0 camera_1]`` subscribes to
``/<camera>/color/image_raw`` and ``/<camera>/depth/image_raw`` (from sim_node or a real
camera driver: sensor-data QoS, so best-effort drivers connect too), writes
``<camera>_color.png`` and ``<camera>_depth.png`` (depth in metres through a colour map,
no-return pixels black) and exits.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import rclpy
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import Image


def image_array(message: Image) -> np.ndarray:
    """rgb8 → (H, W, 3) uint8; 32FC1 → (H, W) float32 metres."""
    if message.encoding == "rgb8":
        return np.frombuffer(bytes(message.data), np.uint8).reshape(
            message.height, message.width, 3
        )
    if message.encoding == "32FC1":
        return np.frombuffer(bytes(message.data), "<f4").reshape(message.height, message.width)
    raise ValueError(f"unsupported encoding {message.encoding!r}")


def save(frames: dict[str, Image], folder: Path) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for key, message in frames.items():
        camera, kind = key
        path = folder / f"{camera}_{kind}.png"
        pixels = image_array(message)
        if kind == "color":
            plt.imsave(path, pixels)
        else:
            shown = np.ma.masked_invalid(pixels)
            colours = plt.get_cmap("viridis").copy()
            colours.set_bad("black")
            plt.imsave(path, shown, cmap=colours)
        written.append(path)
    return written


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="snapshot", description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("."), help="folder for the PNG files")
    parser.add_argument("--cameras", nargs="+", default=["camera_0", "camera_1"])
    parser.add_argument("--timeout", type=float, default=30.0, help="seconds to wait for frames")
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    rclpy.init()
    node = rclpy.create_node("snapshot")
    frames: dict[tuple[str, str], Image] = {}
    for camera in args.cameras:
        for kind in ("color", "depth"):
            node.create_subscription(
                Image,
                f"/{camera}/{kind}/image_raw",
                lambda message, key=(camera, kind): frames.setdefault(key, message),
                qos_profile_sensor_data,
            )
    deadline = time.monotonic() + args.timeout
    wanted = 2 * len(args.cameras)
    while len(frames) < wanted and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
    node.destroy_node()
    rclpy.try_shutdown()
    if len(frames) < wanted:
        missing = [
            f"/{c}/{k}/image_raw"
            for c in args.cameras
            for k in ("color", "depth")
            if (c, k) not in frames
        ]
        print(
            f"snapshot: no frame within {args.timeout} s on {', '.join(missing)}", file=sys.stderr
        )
        return 1
    for path in save(frames, args.out):
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
