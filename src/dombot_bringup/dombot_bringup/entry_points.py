"""The package's console scripts (setup.py), each importing its module inside
``run_quietly`` so that Ctrl-C at any moment, imports included, ends it quietly."""

from dombot_description.console import run_quietly


def bringup() -> int:
    return run_quietly("dombot_bringup.bringup")


def record() -> int:
    return run_quietly("dombot_bringup.record_node")


def replay() -> int:
    return run_quietly("dombot_bringup.replay_node")
