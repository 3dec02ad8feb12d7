"""The vehicle job's nodes for a system ROS 2 Jazzy: ``ros2 launch dombot_bringup
layer_vehicle.launch.py``.

layer_node and vehicle_sim_node with their packages' ``config/<node>.yaml``, as
``bringup --job layer`` starts them; steer with ``/layer/target_radius`` or
``/layer/path`` (docs/LAYER.md).
"""

from launch import LaunchDescription
from launch.substitutions import PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare

# (package, executable, parameters over its config file), as the bring-up starts them
NODES = [
    ("dombot_layer", "layer_node", {"forward_speed": 0.2}),  # bringup --speed
    ("dombot_layer", "vehicle_sim_node", {}),
]


def generate_launch_description() -> LaunchDescription:
    return LaunchDescription(
        [
            Node(
                package=package,
                executable=executable,
                name=executable,
                output="screen",
                parameters=[
                    PathJoinSubstitution(
                        [FindPackageShare(package), "config", f"{executable}.yaml"]
                    ),
                    overrides,
                ],
            )
            for package, executable, overrides in NODES
        ]
    )
