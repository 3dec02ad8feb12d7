"""Which way and how far a crowded pile domino is pushed apart (dombot_bringup.spread)."""

from __future__ import annotations

import numpy as np
import pytest

from dombot_bringup.debris import MAX_SWEEP
from dombot_bringup.spread import (
    SLIDE_DISTANCE,
    STIR_DISTANCE,
    TIP_DISTANCE,
    lay_flat_pushes,
    spread_pushes,
    stir_pushes,
    surfaces,
)

CENTRE = np.array([0.55, -0.30])


def flat(x: float, y: float) -> np.ndarray:
    """A domino lying flat, its length along x."""
    pose = np.eye(4)
    pose[:3, 3] = [x, y, 0.00375]
    return pose


def pushes_of(target: np.ndarray, others: list[np.ndarray], radius: float = 0.12) -> list:
    return spread_pushes(target, others, np.zeros((0, 3)), CENTRE, radius, clearance=0.02)


def test_a_domino_in_a_row_end_to_end_is_pushed_out_sideways_just_far_enough() -> None:
    """Between two neighbours 2 mm from its ends: not along the row (the pusher has no room
    behind it, and the row goes on), but across it, 20 mm clear of both."""
    target = flat(0.50, -0.30)
    pushes = pushes_of(target, [flat(0.45, -0.30), flat(0.55, -0.30)])
    assert pushes
    assert all(abs(direction[0]) < 0.9 for direction, _ in pushes)  # never along the row
    assert all(direction[2] == 0.0 for direction, _ in pushes)
    direction, distance = pushes[0]
    assert abs(direction[1]) > 0.9
    # 24 mm to get past the neighbours' sides, then 20 mm of room: the next step up is 50
    assert distance == pytest.approx(0.05)
    assert all(distance <= MAX_SWEEP for _, distance in pushes)
    moved = target.copy()
    moved[:2, 3] += distance * direction[:2]
    gaps = surfaces([moved])[:, None, :] - surfaces([flat(0.45, -0.30), flat(0.55, -0.30)])
    assert np.linalg.norm(gaps, axis=2).min() >= 0.02 - 1e-9


def test_the_shortest_pushes_come_first_then_those_leading_out_of_the_pile() -> None:
    target = flat(0.50, -0.30)  # 5 cm on the -x side of the pile's centre
    pushes = pushes_of(target, [flat(0.45, -0.30), flat(0.55, -0.30)])
    distances = [distance for _, distance in pushes]
    assert distances == sorted(distances)
    shortest = [direction for direction, distance in pushes if distance == distances[0]]
    assert shortest[0][0] <= shortest[-1][0]  # towards -x (outwards) first


def test_no_push_where_the_pusher_cannot_come_down_behind_the_domino() -> None:
    """A neighbour 6 mm beside its long side leaves the pusher no room there: nothing pushes
    it away from that neighbour."""
    target = flat(0.50, -0.30)
    pushes = pushes_of(target, [flat(0.50, -0.336)])
    assert pushes
    assert all(direction[1] < 0.9 for direction, _ in pushes)


def test_a_domino_alone_needs_only_the_shortest_push_and_none_leaves_the_cameras_view() -> None:
    target = flat(0.55, -0.30)
    alone = pushes_of(target, [])
    assert [distance for _, distance in alone] == pytest.approx([0.02] * len(alone))
    assert len(alone) == 16  # every way
    far_out = flat(0.55, -0.19)  # 11 cm from the centre
    pushes = pushes_of(far_out, [], radius=0.12)
    ends = [far_out[:2, 3] + distance * direction[:2] for direction, distance in pushes]
    assert 0 < len(ends) < 16
    assert all(np.linalg.norm(end - CENTRE) <= 0.12 for end in ends)
    assert pushes_of(target, [flat(0.45, -0.30)], radius=0.01) == []


def test_the_domino_a_pushed_one_lies_on_leaves_the_pusher_room_above_it() -> None:
    """The pusher's tips come down to 0.4 of the pushed domino's height: a domino lying on
    another is pushed off it from above the one below."""
    below = flat(0.48, -0.30)  # sticks out 20 mm behind the one on top
    on_top = flat(0.50, -0.30)
    on_top[2, 3] = 0.01125
    assert any(direction[0] > 0.99 for direction, _ in pushes_of(on_top, [below]))
    beside = flat(0.50, -0.30)  # the same outline on the table: the pusher meets it
    assert not any(direction[0] > 0.99 for direction, _ in pushes_of(beside, [flat(0.46, -0.30)]))


def test_no_push_runs_the_domino_through_a_neighbour_it_does_not_touch() -> None:
    """The planner refuses such a sweep (seed 3's "pushes it into standing_dominoes"):
    past a neighbour 16 mm beside its long side the fingers would have room, but the way
    there is through it."""
    target = flat(0.50, -0.30)
    neighbour = flat(0.50, -0.26)
    # not towards it, even obliquely: the path would graze it
    assert not any(direction[1] > 0.1 for direction, _ in pushes_of(target, [neighbour]))
    assert pushes_of(target, [neighbour])  # the other ways are open


def jam(x: float, end_gap: float) -> tuple[np.ndarray, list[np.ndarray]]:
    """A domino at (x, -0.30) in the middle of five rows side by side 3 mm apart, each row
    of dominoes end to end ``end_gap`` apart."""
    target = flat(x, -0.30)
    rows = [-0.30 + k * 0.027 for k in (-2, -1, 0, 1, 2)]
    ends = [x + k * (0.048 + end_gap) for k in (-2, -1, 0, 1, 2)]
    return target, [flat(e, y) for e in ends for y in rows if (e, y) != (x, -0.30)]


def test_a_jammed_domino_is_pushed_through_its_neighbours_outwards_first() -> None:
    """Every way out of the jam goes through a neighbour: no push frees the fingers. The
    pusher has room only in the 40 mm between the rows' ends: the domino is pushed along
    its row (or obliquely) STIR_DISTANCE, out of the pile first, never out of view."""
    target, neighbours = jam(0.50, end_gap=0.04)
    assert pushes_of(target, neighbours) == []
    stirs = stir_pushes(target, neighbours, np.zeros((0, 3)), CENTRE, 0.12)
    assert stirs and all(distance == STIR_DISTANCE for _, distance in stirs)
    assert all(abs(direction[1]) < 0.5 and direction[2] == 0.0 for direction, _ in stirs)
    assert stirs[0][0][0] == pytest.approx(-1.0)  # away from the pile's centre (+x of it)
    ends = [target[:2, 3] + distance * direction[:2] for direction, distance in stirs]
    assert all(np.linalg.norm(end - CENTRE) <= 0.12 for end in ends)
    assert stir_pushes(target, neighbours, np.zeros((0, 3)), CENTRE, 0.01) == []


def test_no_stir_where_the_pusher_cannot_come_down_beside_the_jammed_domino() -> None:
    target, neighbours = jam(0.50, end_gap=0.003)  # packed: 3 mm between ends too
    assert stir_pushes(target, neighbours, np.zeros((0, 3)), CENTRE, 0.12) == []


def on_edge(x: float, y: float) -> np.ndarray:
    """A domino standing on its long edge (body y up), its length along x, its thickness
    axis along -y."""
    pose = np.eye(4)
    pose[:3, :3] = np.column_stack([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
    pose[:3, 3] = [x, y, 0.012]
    return pose


def test_a_domino_on_its_edge_is_pushed_over_along_its_thickness_towards_the_centre_first():
    (first, towards), (second, back) = lay_flat_pushes(on_edge(0.55, -0.25), CENTRE)
    assert first == pytest.approx([0.0, -1.0, 0.0])  # over towards the pile's centre
    assert second == pytest.approx([0.0, 1.0, 0.0])
    assert towards == back == TIP_DISTANCE


def test_a_flat_domino_out_of_reach_is_slid_towards_the_centre_unless_it_lies_there() -> None:
    ((direction, distance),) = lay_flat_pushes(flat(0.45, -0.30), CENTRE)
    assert direction == pytest.approx([1.0, 0.0, 0.0])
    assert distance == SLIDE_DISTANCE
    assert lay_flat_pushes(flat(0.555, -0.30), CENTRE) == []
