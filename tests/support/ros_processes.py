"""Start ROS 2 code in separate OS processes, so tests cross real DDS."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def python_process(source: str) -> Iterator[subprocess.Popen[str]]:
    """Run ``source`` in a child interpreter with this session's environment."""
    child = subprocess.Popen(
        [sys.executable, "-c", textwrap.dedent(source)],
        env=dict(os.environ),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        yield child
    finally:
        child.terminate()
        try:
            child.wait(timeout=10)
        except subprocess.TimeoutExpired:
            child.kill()
            child.wait()
