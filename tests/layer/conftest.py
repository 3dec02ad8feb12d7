"""Collect the ROS node test only where the ROS interfaces are importable.

The kinematics, path and simulation tests are pure Python and run anywhere;
``test_layer_node.py`` needs the workspace's ROS environment (``./dombot test``).
"""

from __future__ import annotations

import importlib.util

collect_ignore = [] if importlib.util.find_spec("dombot_msgs") else ["test_layer_node.py"]
