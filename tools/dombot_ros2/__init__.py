"""DOM-BOT's stand-in for ros2cli, for machines where ROS 2 came from PyPI wheels.

Provides the everyday verbs (run, pkg, topic, service, interface, node) with
ros2cli's output formats, and hands over to a real ``ros2`` whenever one is
installed. See docs/ROS2CLI.md.
"""
