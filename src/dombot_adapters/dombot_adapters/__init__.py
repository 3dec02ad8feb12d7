"""What every DOM-BOT node adapter shares and the plain modules must not import: message
conversions (4×4 poses, times), a quiet end on Ctrl-C, and settings dataclasses as ROS
parameters. The ROS-free packages (``dombot_description`` and every algorithm module)
never import this package; the ``*_node.py`` adapters do.
"""
