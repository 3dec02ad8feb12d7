"""``ros2 run`` and ``ros2 pkg``: executables found through the ament index as ros2run does."""

from __future__ import annotations

import os
import shlex
import signal
import subprocess
from pathlib import Path

from ament_index_python.packages import (
    PackageNotFoundError,
    get_package_prefix,
    get_package_share_directory,
    get_packages_with_prefixes,
)


class CommandError(RuntimeError):
    """A user error: printed to stderr as is, exit status 1."""


def package_prefix(package: str) -> Path:
    try:
        return Path(get_package_prefix(package))
    except (PackageNotFoundError, ValueError):
        raise CommandError(f"Package '{package}' not found") from None


def executable_paths(package: str) -> list[Path]:
    """Executable files under <prefix>/lib/<package>/, hidden folders skipped (ros2pkg's rule)."""
    base = package_prefix(package) / "lib" / package
    paths = []
    for folder, subfolders, files in os.walk(base):
        subfolders[:] = sorted(d for d in subfolders if not d.startswith("."))
        paths.extend(
            Path(folder) / name for name in sorted(files) if os.access(Path(folder) / name, os.X_OK)
        )
    return paths


def executable_path(package: str, executable: str) -> Path:
    matches = [path for path in executable_paths(package) if path.name == executable]
    if not matches:
        raise CommandError("No executable found")
    if len(matches) > 1:
        raise CommandError("Multiple executables found:" + "".join(f"\n- {p}" for p in matches))
    return matches[0]


def run(package: str, executable: str, arguments: list[str], prefix: str | None) -> int:
    """Run like ros2run: forward SIGINT/SIGTERM to the child and return its exit code."""
    command = [*shlex.split(prefix or ""), str(executable_path(package, executable)), *arguments]
    child = subprocess.Popen(command)

    def forward(signum: int, _frame: object) -> None:
        child.send_signal(signum)

    previous = {sig: signal.signal(sig, forward) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        return child.wait()
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def list_packages() -> list[str]:
    return sorted(get_packages_with_prefixes())


def prefix(package: str, share: bool) -> str:
    if share:
        try:
            return get_package_share_directory(package)
        except (PackageNotFoundError, ValueError):
            raise CommandError(f"Package '{package}' not found") from None
    return str(package_prefix(package))


def executables(package: str | None, full_path: bool) -> list[str]:
    packages = [package] if package else list_packages()
    lines = []
    for name in packages:
        for path in executable_paths(name):
            lines.append(str(path) if full_path else f"{name} {path.name}")
    return lines
