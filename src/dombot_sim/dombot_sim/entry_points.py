"""The package's console scripts (setup.py), each importing its module inside
``run_quietly`` so that Ctrl-C at any moment, imports included, ends it quietly; sim_node
with glibc's malloc for Python objects, as it takes huge goals."""

from dombot_description.console import run_quietly, run_with_system_malloc


def sim_node() -> int:
    return run_with_system_malloc("dombot_sim.sim_node")


def snapshot() -> int:
    return run_quietly("dombot_sim.snapshot")
