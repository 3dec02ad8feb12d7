"""How a cell implementation differs from the ``Cell`` protocol the task core calls.

Python does not check a Protocol's signatures at run time, and the task core passes
arguments by position: a ``meanwhile`` callback given where an implementation expects a
timeout would fail only on the robot. So an implementation takes the protocol's
positional parameters first and in order, its keyword-only ones by keyword only, any
extra one with a default; and ``meanwhile`` is keyword-only everywhere (the protocol's
too).
"""

from __future__ import annotations

import inspect

from dombot_bringup.task.cell import Cell

KEYWORD_ONLY = inspect.Parameter.KEYWORD_ONLY


def protocol_members() -> list[str]:
    return [name for name in vars(Cell) if not name.startswith("_")]


def differences(implementation: type) -> list[str]:
    """Where ``implementation`` takes a member otherwise than ``Cell`` does (none: [])."""
    found = []
    for name in protocol_members():
        wanted = inspect.getattr_static(Cell, name)
        given = inspect.getattr_static(implementation, name, None)
        if isinstance(wanted, property) or given is None:
            if not isinstance(given, property):
                found.append(f"{name}: missing or not a property")
            continue
        asked = inspect.signature(wanted).parameters
        takes = inspect.signature(given).parameters
        by_position = [n for n, p in asked.items() if p.kind is not KEYWORD_ONLY]
        taken = [n for n, p in takes.items() if p.kind is not KEYWORD_ONLY]
        if taken[: len(by_position)] != by_position:
            found.append(f"{name}: takes {taken} by position, not {by_position} first")
        for n, p in asked.items():
            if p.kind is KEYWORD_ONLY and (n not in takes or takes[n].kind is not KEYWORD_ONLY):
                found.append(f"{name}: {n} not keyword-only")
        for n, p in takes.items():
            if n not in asked and p.default is p.empty:
                found.append(f"{name}: {n} has no default")
        for side, parameters in (("Cell", asked), (implementation.__name__, takes)):
            if "meanwhile" in parameters and parameters["meanwhile"].kind is not KEYWORD_ONLY:
                found.append(f"{name}: {side}'s meanwhile not keyword-only")
    return found
