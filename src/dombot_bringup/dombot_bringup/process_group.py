"""Run several node processes like a launch file, without ROS's launch package.

``launch``/``launch_ros`` cannot be installed on machines without a system ROS 2,
so the bring-up starts its nodes with this small supervisor: each child gets its
own process group, its output is forwarded line by line with a ``[name]`` prefix
(the bring-up's own lines, ``say``, are ``[bringup]``; no two lines interleave),
the last lines are kept for the report when a node dies, and stopping sends
SIGINT, then SIGTERM, then SIGKILL, the escalation ros2 launch uses. Inside ``with
ProcessGroup()`` a SIGINT or SIGTERM to the bring-up raises KeyboardInterrupt, so the
block unwinds and its nodes are stopped (in their own sessions, a signal to the
bring-up's process group does not reach them; rclpy's own SIGTERM handler would only
shut its context down, and the job waited for answers for minutes). A process
started ``restartable`` (a stateless server: perception, planner) is started again
when it dies, like launch's ``respawn``; the caller sees its ``restarts`` count grow
and sends again what it had asked of it. On Linux each
child also gets SIGTERM from the kernel if the supervisor dies without stopping it
(``PR_SET_PDEATHSIG``), so a killed bring-up leaves no orphaned nodes behind.
"""

from __future__ import annotations

import collections
import contextlib
import ctypes
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import FrameType
from typing import TextIO

TAIL_LINES = 20
MAX_RESTARTS = 3  # per process: one that keeps dying is reported, not restarted forever
PR_SET_PDEATHSIG = 1  # linux/prctl.h
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)  # Ctrl-C; a CI's or a user's kill
BRINGUP = "bringup"  # the name on the bring-up's own lines, beside its nodes' names
# one line at a time into the output, from the forwarding threads and the bring-up alike;
# reentrant: a signal handler's line may come while the main thread writes one
_LINE_LOCK = threading.RLock()


def write_line(name: str, line: str, sink: TextIO | None = None) -> None:
    """``line`` as ``[name] line`` into ``sink`` (default: the current sys.stdout), whole."""
    sink = sys.stdout if sink is None else sink
    # the reader of the output gone (a killed benchmark): the line is lost, not the stop
    with _LINE_LOCK, contextlib.suppress(BrokenPipeError):
        sink.write(f"[{name}] {line}\n")
        sink.flush()


def say(message: str, sink: TextIO | None = None) -> None:
    """A line of the bring-up's own, named like the nodes' forwarded lines."""
    write_line(BRINGUP, message, sink)


def resident_mb(pid: int | str = "self") -> float | None:
    """A process's resident memory (VmRSS) in MB, from /proc; None where there is none
    (not Linux, or the process is gone)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return None
    for line in status.splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0  # kB
    return None


@contextlib.contextmanager
def handling(handler: Callable[[int, FrameType | None], None]) -> Iterator[None]:
    """``handler`` for SIGINT and SIGTERM while the block runs, the previous handlers
    after; nothing off the main thread (Python runs handlers there only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {signum: signal.signal(signum, handler) for signum in STOP_SIGNALS}
    try:
        yield
    finally:
        for signum, old in previous.items():
            if old is not None:  # None: a handler not set from Python (rclpy's, in C)
                signal.signal(signum, old)


def end_process(process: subprocess.Popen, grace: float) -> int:
    """Stop ``process``: SIGTERM, then SIGKILL after ``grace`` s; its exit code."""
    process.terminate()
    try:
        return process.wait(timeout=grace)
    except subprocess.TimeoutExpired:
        process.kill()
        return process.wait()


def _die_with_parent() -> None:
    """In the child before exec: ask for SIGTERM when the supervising process dies."""
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)


class NodeDiedError(RuntimeError):
    """A supervised process exited while it was still needed."""

    def __init__(self, name: str, returncode: int, tail: Sequence[str]) -> None:
        self.name = name
        self.returncode = returncode
        self.tail = list(tail)
        last = "\n".join(f"    {line}" for line in self.tail) or "    (no output)"
        super().__init__(f"node '{name}' died with exit code {returncode}; last output:\n{last}")


@dataclass
class ManagedProcess:
    """One child process with forwarded, remembered output."""

    name: str
    command: Sequence[str]
    env: dict[str, str] | None = None
    restartable: bool = False
    restarts: int = 0
    on_line: Callable[[str], None] | None = None  # sees each output line (e.g. a URL)
    process: subprocess.Popen[str] | None = None
    tail: collections.deque[str] = field(
        default_factory=lambda: collections.deque(maxlen=TAIL_LINES)
    )
    _reader: threading.Thread | None = None

    def start(self, sink: TextIO) -> None:
        self.process = subprocess.Popen(
            list(self.command),
            env=self.env,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            text=True,
            bufsize=1,
            start_new_session=True,
            preexec_fn=_die_with_parent if sys.platform.startswith("linux") else None,
        )
        self._reader = threading.Thread(target=self._forward, args=(sink,), daemon=True)
        self._reader.start()

    def _forward(self, sink: TextIO) -> None:
        assert self.process is not None and self.process.stdout is not None
        for raw in self.process.stdout:
            line = raw.rstrip("\n")
            self.tail.append(line)
            if self.on_line is not None:
                self.on_line(line)
            write_line(self.name, line, sink)

    @property
    def returncode(self) -> int | None:
        return None if self.process is None else self.process.poll()

    def signal(self, signum: int) -> None:
        if self.process is not None and self.process.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.process.pid, signum)

    def wait(self, timeout: float) -> bool:
        """Wait for exit; True if the process has exited."""
        if self.process is None:
            return True
        try:
            self.process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            return False
        if self._reader is not None:
            self._reader.join(timeout=2.0)
        return True


class ProcessGroup:
    """Start, watch and stop a set of node processes."""

    def __init__(self, sink: TextIO = sys.stdout, stop_timeout: float = 5.0) -> None:
        self._sink = sink
        self._stop_timeout = stop_timeout
        self.processes: list[ManagedProcess] = []
        self._interrupted = False  # a SIGINT or SIGTERM is unwinding the with block

    def start(
        self,
        name: str,
        command: Sequence[str],
        env: dict[str, str] | None = None,
        restartable: bool = False,
        on_line: Callable[[str], None] | None = None,
    ) -> ManagedProcess:
        managed = ManagedProcess(
            name=name, command=command, env=env, restartable=restartable, on_line=on_line
        )
        managed.start(self._sink)
        self.processes.append(managed)
        return managed

    def check(self) -> None:
        """Restart a restartable process that has exited; raise NodeDiedError for any other
        (or for one that has used its MAX_RESTARTS)."""
        for managed in self.processes:
            code = managed.returncode
            if code is None:
                continue
            managed.wait(timeout=2.0)
            if not managed.restartable or managed.restarts >= MAX_RESTARTS:
                raise NodeDiedError(managed.name, code, managed.tail)
            managed.restarts += 1
            say(
                f"node '{managed.name}' died with exit code {code}; starting it again "
                f"(restart {managed.restarts} of {MAX_RESTARTS})",
                self._sink,
            )
            managed.start(self._sink)

    def restarts(self) -> dict[str, int]:
        """How often each process has been started again."""
        return {managed.name: managed.restarts for managed in self.processes}

    def resident_mb(self) -> dict[str, float]:
        """The bring-up's and each running process's resident memory [MB]."""
        running = [(BRINGUP, "self")] + [
            (managed.name, managed.process.pid)
            for managed in self.processes
            if managed.process is not None and managed.returncode is None
        ]
        sizes = {name: resident_mb(pid) for name, pid in running}
        return {name: mb for name, mb in sizes.items() if mb is not None}

    def wait_until(self, ready: Callable[[], bool], timeout: float, what: str) -> None:
        """Poll ``ready`` while checking that no node died; TimeoutError names ``what``."""
        deadline = time.monotonic() + timeout
        while not ready():
            self.check()
            if time.monotonic() > deadline:
                raise TimeoutError(f"timed out after {timeout:.0f} s waiting for {what}")
            time.sleep(0.1)

    def stop(self) -> dict[str, int | None]:
        """Stop every process (SIGINT → SIGTERM → SIGKILL, ``stop_timeout`` s apart; each
        step past SIGINT logged); return their exit codes. A SIGINT or SIGTERM meanwhile
        is logged, not obeyed: it would cut the escalation short."""
        with handling(self._already_stopping):
            for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
                alive = [p for p in self.processes if p.returncode is None]
                if not alive:
                    break
                if signum != signal.SIGINT:
                    names = ", ".join(managed.name for managed in alive)
                    say(
                        f"{names} still running after {self._stop_timeout:.0f} s: "
                        f"sending {signal.Signals(signum).name}",
                        self._sink,
                    )
                for managed in alive:
                    managed.signal(signum)
                deadline = time.monotonic() + self._stop_timeout
                for managed in alive:
                    managed.wait(timeout=max(0.0, deadline - time.monotonic()))
        return {p.name: p.returncode for p in self.processes}

    def _interrupt(self, signum: int, frame: FrameType | None) -> None:
        """SIGINT or SIGTERM to the bring-up: unwind the ``with`` block, which stops the
        nodes; once only (``ros2 run`` forwards a group's SIGTERM as a second one, which
        must not cut the unwinding short before the stop)."""
        if self._interrupted:
            self._already_stopping(signum, frame)
            return
        self._interrupted = True
        say(f"{signal.Signals(signum).name}: stopping the nodes", self._sink)
        raise KeyboardInterrupt

    def _already_stopping(self, signum: int, _frame: FrameType | None) -> None:
        say(f"{signal.Signals(signum).name}: already stopping the nodes", self._sink)

    def __enter__(self) -> ProcessGroup:
        self._handlers = contextlib.ExitStack()
        self._handlers.enter_context(handling(self._interrupt))
        return self

    def __exit__(self, *exc_info: object) -> None:
        try:
            self.stop()
        finally:
            self._handlers.close()
