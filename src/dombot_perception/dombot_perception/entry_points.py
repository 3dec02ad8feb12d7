"""The package's console scripts (setup.py), each importing its module inside
``run_quietly`` so that Ctrl-C at any moment, imports included, ends it quietly."""

from dombot_description.console import run_quietly


def perception_node() -> int:
    return run_quietly("dombot_perception.perception_node")
