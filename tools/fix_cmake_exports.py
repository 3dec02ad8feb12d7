"""Point the ROS 2 wheels' exported CMake files at this interpreter's headers.

The PyPI ROS 2 Jazzy wheels were built in a manylinux container; their
``share/*/cmake/*Export.cmake`` files name that container's Python and numpy
include directories, so ``colcon build`` of an interface package fails with
"imported target includes non-existent path". Rewriting those two paths to the
venv's own (``sysconfig`` and ``numpy.get_include()``) is all it takes.
Idempotent: files already pointing here are left untouched.
"""

from __future__ import annotations

import re
import sys
import sysconfig
from pathlib import Path

import numpy

BUILDER_PYTHON_INCLUDE = re.compile(r"/opt/python/cp\d+-cp\d+/include/python3\.\d+")
BUILDER_NUMPY_INCLUDE = re.compile(
    r"/opt/python/cp\d+-cp\d+/lib/python3\.\d+/site-packages/numpy/_core/include"
)


def fix_file(path: Path, python_include: str, numpy_include: str) -> bool:
    """Rewrite one export file; return True if it changed."""
    text = path.read_text()
    fixed = BUILDER_NUMPY_INCLUDE.sub(numpy_include, text)
    fixed = BUILDER_PYTHON_INCLUDE.sub(python_include, fixed)
    if fixed == text:
        return False
    path.write_text(fixed)
    return True


def main(prefix: str) -> int:
    share = Path(prefix) / "share"
    if not share.is_dir():
        print(f"fix_cmake_exports: no share/ directory under {prefix}", file=sys.stderr)
        return 2
    python_include = sysconfig.get_paths()["include"]
    numpy_include = numpy.get_include()
    changed = [
        path
        for path in share.glob("*/cmake/*Export.cmake")
        if fix_file(path, python_include, numpy_include)
    ]
    print(f"fix_cmake_exports: rewrote {len(changed)} export file(s) under {share}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else sys.prefix))
