"""The latest transform of every frame, and lookups along the chain between two frames.

A minimal stand-in for tf2's buffer (no tf2_ros wheel is installable here): tf's tree
gives each frame one parent; this keeps the newest transform per child, from /tf and
/tf_static alike, without history or interpolation. That suits what perception asks:
where a rigidly mounted camera is (a real cell's calibration), not where a moving frame
was at an image's stamp. Transforms are kept as they arrive (translation, quaternion) and
turned into matrices only along a chain that is looked up: /tf brings hundreds per
second, lookups come a few times per detection. ROS-free; thread-safe (messages arrive
on executor threads).
"""

from __future__ import annotations

import threading

import numpy as np
from scipy.spatial.transform import Rotation

MAX_DEPTH = 1000  # frames in one chain: more means a loop


class TransformBuffer:
    def __init__(self) -> None:
        self._parent: dict[str, tuple[str, tuple[float, ...], tuple[float, ...]]] = {}
        self._lock = threading.Lock()

    def set(
        self,
        parent: str,
        child: str,
        translation: tuple[float, float, float],
        quaternion: tuple[float, float, float, float],
    ) -> None:
        """``child``'s pose in ``parent`` (quaternion x, y, z, w as tf sends it, normalised
        when used); replaces what ``child`` had before."""
        with self._lock:
            self._parent[child] = (parent, tuple(translation), tuple(quaternion))

    def lookup(self, target: str, source: str) -> np.ndarray:
        """X_TS: the pose of frame ``source`` in frame ``target``. LookupError names the
        frame that is missing or the two trees that are not connected."""
        with self._lock:
            known = self._parent.keys() | {entry[0] for entry in self._parent.values()}
            unknown = [frame for frame in (target, source) if frame not in known]
            if unknown and target != source:
                raise LookupError(f"no transform has frame {' or '.join(map(repr, unknown))}")
            root_t, x_rt = self._to_root(target)
            root_s, x_rs = self._to_root(source)
        if root_t != root_s:
            raise LookupError(
                f"no transform chain between {target!r} (tree of {root_t!r}) "
                f"and {source!r} (tree of {root_s!r})"
            )
        return np.linalg.inv(x_rt) @ x_rs

    def _to_root(self, frame: str) -> tuple[str, np.ndarray]:
        """The root of ``frame``'s tree and ``frame``'s pose in it."""
        x_rf = np.eye(4)
        for _ in range(MAX_DEPTH):
            if frame not in self._parent:
                return frame, x_rf
            frame, translation, quaternion = self._parent[frame]
            x_pf = np.eye(4)
            x_pf[:3, :3] = Rotation.from_quat(quaternion).as_matrix()
            x_pf[:3, 3] = translation
            x_rf = x_pf @ x_rf
        raise LookupError(f"the frames above {frame!r} form a loop")
