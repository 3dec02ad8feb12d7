"""The arm job's nodes for a system ROS 2 Jazzy: ``ros2 launch dombot_bringup
arm_cell.launch.py [real_time_factor:=0.0] [meshcat:=true]``.

The same node set and parameters the bring-up starts (docs/BRINGUP.md), each on top of
its package's ``config/<node>.yaml``; the job itself (pour, build, strike) stays
``ros2 run dombot_bringup bringup``, or your own client of the services.
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare

# sim_node's parameters that the bring-up's options set, with their defaults
ARGUMENTS = {"real_time_factor": "1.0", "meshcat": "false"}
# (package, executable, parameters over its config file), as the bring-up starts them
NODES = [
    ("dombot_sim", "sim_node", {"domino_count": 0}),
    ("dombot_perception", "perception_node", {"use_sim_time": True, "continuous": False}),
    ("dombot_planner", "planner_node", {"use_sim_time": True}),
]


def generate_launch_description() -> LaunchDescription:
    from_arguments = {name: LaunchConfiguration(name) for name in ARGUMENTS}
    nodes = [
        Node(
            package=package,
            executable=executable,
            name=executable,
            output="screen",
            parameters=[
                PathJoinSubstitution([FindPackageShare(package), "config", f"{executable}.yaml"]),
                overrides | (from_arguments if executable == "sim_node" else {}),
            ],
        )
        for package, executable, overrides in NODES
    ]
    arguments = [
        DeclareLaunchArgument(name, default_value=value) for name, value in ARGUMENTS.items()
    ]
    return LaunchDescription([*arguments, *nodes])
