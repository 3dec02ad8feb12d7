"""The package's console scripts (setup.py), each importing its module inside
``run_quietly`` so that Ctrl-C at any moment, imports included, ends it quietly; the
node with glibc's malloc for Python objects, as it takes huge requests."""

from dombot_description.console import run_with_system_malloc


def planner_node() -> int:
    return run_with_system_malloc("dombot_planner.planner_node")
