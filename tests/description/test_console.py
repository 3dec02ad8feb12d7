"""Ctrl-C at any moment, imports included, ends every DOM-BOT executable quietly."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from dombot_description.console import INTERRUPTED
from support.ros_processes import executable_path

SLOW_MODULE = """
import sys, time
print("importing", flush=True)
time.sleep(60)  # an import that takes a while, as Drake's does
def main():
    return 0
"""

EXECUTABLES = [
    ("dombot_sim", "sim_node"),
    ("dombot_perception", "perception_node"),
    ("dombot_planner", "planner_node"),
    ("dombot_layer", "layer_node"),
    ("dombot_layer", "vehicle_sim_node"),
    ("dombot_bringup", "bringup"),
]


def test_ctrl_c_while_the_node_module_imports_ends_quietly(tmp_path: Path) -> None:
    (tmp_path / "slow_node.py").write_text(SLOW_MODULE)
    code = "from dombot_description.console import run_quietly; exit(run_quietly('slow_node'))"
    env = dict(os.environ, PYTHONPATH=f"{tmp_path}{os.pathsep}{os.environ.get('PYTHONPATH', '')}")
    child = subprocess.Popen(
        [sys.executable, "-c", code], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    assert child.stdout.readline() == b"importing\n"
    child.send_signal(signal.SIGINT)
    _, error = child.communicate(timeout=120)
    assert child.returncode == INTERRUPTED
    assert error == b""


def test_a_node_run_with_system_malloc_is_the_same_process_with_pythonmalloc_malloc(
    tmp_path: Path,
) -> None:
    (tmp_path / "probe_node.py").write_text(
        "import os, sys\n"
        "def main():\n"
        "    print(os.getpid(), os.environ['PYTHONMALLOC'], sys.argv[1:], flush=True)\n"
    )
    code = (
        "from dombot_description.console import run_with_system_malloc; "
        "exit(run_with_system_malloc('probe_node'))"
    )
    env = dict(os.environ, PYTHONPATH=f"{tmp_path}{os.pathsep}{os.environ.get('PYTHONPATH', '')}")
    env.pop("PYTHONMALLOC", None)
    child = subprocess.Popen(
        [sys.executable, "-c", code, "--ros-args"],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    output, error = child.communicate(timeout=120)
    assert child.returncode == 0, error
    pid, allocator, arguments = output.decode().split(" ", 2)
    assert int(pid) == child.pid  # run again in place: a supervisor's signals still reach it
    assert allocator == "malloc"
    assert arguments.strip() == "['--ros-args']"


def _loaded(pid: int, library: str) -> bool:
    try:
        return library in Path(f"/proc/{pid}/maps").read_text()
    except OSError:
        return False


@pytest.mark.skipif(not Path("/proc/self/maps").exists(), reason="needs Linux /proc")
@pytest.mark.slow
@pytest.mark.parametrize(("package", "executable"), EXECUTABLES)
def test_ctrl_c_during_start_up_leaves_no_traceback(
    package: str, executable: str, tmp_path: Path
) -> None:
    """SIGINT once rclpy's library is loaded: the executable is importing the rest of its
    modules or already starting; either way it ends without a traceback."""
    path = executable_path(package, executable)
    arguments = ["--out", str(tmp_path)] if executable == "bringup" else []
    child = subprocess.Popen(
        [str(path), *arguments], stdout=subprocess.PIPE, stderr=subprocess.STDOUT
    )
    try:
        deadline = time.monotonic() + 120
        while not _loaded(child.pid, "_rclpy_pybind11") and time.monotonic() < deadline:
            time.sleep(0.01)
        assert _loaded(child.pid, "_rclpy_pybind11"), f"{executable} never imported rclpy"
        output = _interrupted(child)
    finally:
        _killed_if_running(child)
    text = output.decode(errors="replace")
    assert "Traceback" not in text and "KeyboardInterrupt" not in text, text
    assert child.returncode in (0, INTERRUPTED), text


@pytest.mark.slow
@pytest.mark.parametrize(
    ("package", "executable", "started"),
    [
        ("dombot_layer", "layer_node", "ready:"),
        ("dombot_layer", "vehicle_sim_node", "simulating"),
    ],
)
def test_ctrl_c_while_a_node_spins_leaves_no_traceback(
    package: str, executable: str, started: str
) -> None:
    """SIGINT shuts rclpy's context down under the spinning executor, whose next wait then
    fails ('the given context is not valid'): that is a normal stop too."""
    path = executable_path(package, executable)
    child = subprocess.Popen(
        [str(path)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )
    try:
        lines = []
        while not any(started in line for line in lines):
            line = child.stdout.readline()
            assert line, f"{executable} ended before it started: {''.join(lines)}"
            lines.append(line)
        output = _interrupted(child)
    finally:
        _killed_if_running(child)
    assert "Traceback" not in output, output
    assert child.returncode in (0, INTERRUPTED), output


def _interrupted(child: subprocess.Popen):
    """Ctrl-C to ``child``: all it printed until it ended."""
    child.send_signal(signal.SIGINT)
    output, _ = child.communicate(timeout=120)
    return output


def _killed_if_running(child: subprocess.Popen) -> None:
    if child.poll() is None:
        child.kill()
        child.wait()
