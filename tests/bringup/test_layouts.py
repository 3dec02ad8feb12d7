"""Run layouts: spacing along the curve, facing along the run, validation messages."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dombot_bringup import layouts
from dombot_bringup.layouts import BuildArea, LayoutError

AREA = BuildArea(x_min=0.3, x_max=0.8, y_min=-0.1, y_max=0.5, reach_min=0.35, reach_max=0.8)


def gaps(placements: list[layouts.DominoPlacement]) -> np.ndarray:
    xy = np.array([[p.x, p.y] for p in placements])
    return np.linalg.norm(np.diff(xy, axis=0), axis=1)


def test_line_is_evenly_spaced_at_sixty_percent_of_the_height() -> None:
    run = layouts.line((0.5, 0.0), heading=math.pi / 2, count=5)
    assert gaps(run) == pytest.approx(np.full(4, 0.6 * 0.048))
    assert all(p.heading == pytest.approx(math.pi / 2) for p in run)


def test_upright_orientation_points_body_x_up_and_body_z_along_the_run() -> None:
    placement = layouts.DominoPlacement(index=0, x=0.5, y=0.1, heading=0.7)
    w, x, y, z = placement.quaternion_wxyz()
    rotation = Rotation.from_quat([x, y, z, w]).as_matrix()
    assert rotation[:, 0] == pytest.approx([0, 0, 1], abs=1e-12)
    assert rotation[:, 2] == pytest.approx([math.cos(0.7), math.sin(0.7), 0], abs=1e-12)
    assert placement.z == pytest.approx(0.024)


def test_arc_chord_spacing_and_tangent_headings() -> None:
    run = layouts.arc(center=(0.5, 0.2), radius=0.15, start_angle=-math.pi / 2, count=10)
    # Arc-length spacing 28.8 mm on r = 150 mm: the chord is 2 r sin(s / 2r).
    expected_chord = 2 * 0.15 * math.sin(0.0288 / 0.3)
    assert gaps(run) == pytest.approx(np.full(9, expected_chord), rel=1e-6)
    for p in run:
        radial = math.atan2(p.y - 0.2, p.x - 0.5)
        assert math.remainder(p.heading - radial - math.pi / 2, 2 * math.pi) == pytest.approx(
            0, abs=1e-4
        )
    layouts.validate(run, AREA)


@pytest.mark.parametrize(
    "make",
    [
        lambda: layouts.s_curve((0.45, 0.0), math.pi / 2, 0.45, 0.06, count=15),
        lambda: layouts.spiral((0.55, 0.2), 0.06, 0.05, count=12),
        lambda: layouts.polyline(np.array([[0.45, 0.0], [0.55, 0.15], [0.5, 0.3]]), count=12),
        lambda: layouts.circle((0.55, 0.2), 0.1),
    ],
    ids=["s_curve", "spiral", "polyline", "circle"],
)
def test_curved_layouts_keep_arc_spacing_and_validate(make) -> None:
    run = make()
    # Chords on a curve are at most the arc spacing and close to it at these radii.
    assert np.all(gaps(run) <= 0.0288 + 1e-6)
    assert np.all(gaps(run) > 0.027)
    layouts.validate(run, AREA)


def test_csv_layout_with_header(tmp_path) -> None:
    path = tmp_path / "run.csv"
    path.write_text("x,y\n0.5,0.0\n0.5,0.2\n")
    run = layouts.from_csv(path)
    assert len(run) == int(0.2 // 0.0288) + 1
    assert run[-1].y == pytest.approx((len(run) - 1) * 0.0288)


def test_bad_csv_row_names_the_line(tmp_path) -> None:
    path = tmp_path / "run.csv"
    path.write_text("0.5,0.0\n0.5,oops\n")
    with pytest.raises(LayoutError, match=r"run.csv:2"):
        layouts.from_csv(path)


def test_csv_with_a_utf8_byte_order_mark_keeps_its_first_point(tmp_path) -> None:
    path = tmp_path / "run.csv"
    path.write_text("0.5,0.0\n0.5,0.2\n", encoding="utf-8-sig")
    run = layouts.from_csv(path)
    assert (run[0].x, run[0].y) == pytest.approx((0.5, 0.0))
    assert len(run) == int(0.2 // 0.0288) + 1


@pytest.mark.parametrize(
    ("write", "reason"),
    [
        (lambda path: path.mkdir(), "it is a directory, not a file"),
        (lambda path: None, "No such file or directory"),
        (lambda path: path.write_text("0.5,0.0\n0.5,0.2\n", encoding="utf-16"), "it is not UTF-8"),
        (
            lambda path: path.write_text("0.5,0.0\n0.5,0.2\n", encoding="utf-16-le"),
            "it is not UTF-8",
        ),
    ],
    ids=["directory", "missing", "utf16_with_bom", "utf16_without_bom"],
)
def test_an_unreadable_csv_is_refused_with_what_is_wrong(tmp_path, write, reason: str) -> None:
    path = tmp_path / "run.csv"
    write(path)
    with pytest.raises(LayoutError, match=rf"cannot read --csv .*run.csv: {reason}"):
        layouts.from_csv(path)


def test_validation_names_the_first_domino_outside_the_area() -> None:
    run = layouts.line((0.5, 0.4), heading=math.pi / 2, count=8)
    with pytest.raises(
        LayoutError, match=r"domino 4 at \(0\.500, 0\.515\) m is outside the build area"
    ):
        layouts.validate(run, AREA)


def test_validation_names_an_unreachable_domino() -> None:
    area = BuildArea(x_min=0.0, x_max=1.0, y_min=-1.0, y_max=1.0, reach_min=0.35, reach_max=0.8)
    run = layouts.line((0.7, 0.0), heading=0.0, count=6)
    with pytest.raises(LayoutError, match=r"domino 4 .* 0\.815 m from the arm base"):
        layouts.validate(run, area)


def test_validation_names_an_overlapping_domino() -> None:
    run = layouts.line((0.5, 0.0), heading=math.pi / 2, count=3)
    clash = layouts.DominoPlacement(index=3, x=0.505, y=0.0, heading=0.0)
    with pytest.raises(LayoutError, match=r"domino 3 .* overlaps domino 0"):
        layouts.validate([*run, clash], AREA)


@pytest.mark.parametrize("spacing", [0.005, 0.013, 0.06, float("nan")])
def test_spacing_that_would_not_topple_is_refused(spacing: float) -> None:
    with pytest.raises(LayoutError, match="spacing"):
        layouts.line((0.5, 0.0), 0.0, 3, spacing=spacing)


def test_too_many_dominoes_for_the_shape() -> None:
    with pytest.raises(LayoutError, match=r"need .* of curve"):
        layouts.arc((0.5, 0.2), 0.05, 0.0, count=20)


@pytest.mark.parametrize(
    ("spacing", "count", "section", "gaps"),
    [
        (None, 10, 4, [4]),  # 28.8 mm: one empty slot leaves 57.6 mm > 55.5 mm
        (None, 14, 4, [4, 9]),
        (0.02, 10, 3, [3, 4]),  # 20 mm: two slots (60 mm); the next gap would end the run
        (None, 5, 4, []),  # the gap would be the last slot: nothing behind it to protect
        (None, 10, 0, []),
    ],
)
def test_safety_gaps_part_the_run_into_sections_no_fall_can_cross(
    spacing: float | None, count: int, section: int, gaps: list[int]
) -> None:
    """Every gap leaves the dominoes either side further apart than a toppling domino
    reaches (height + thickness), after every ``section`` dominoes."""
    placements = layouts.line((0.45, 0.0), math.pi / 2, count, spacing)
    assert [i for gap in layouts.safety_gaps(placements, section) for i in gap] == gaps
    reach = layouts.DOMINO_LENGTH + layouts.DOMINO_THICKNESS
    standing = [p for p in placements if p.index not in gaps]
    for before, after in itertools.pairwise(standing):
        if after.index - before.index > 1:
            assert math.hypot(after.x - before.x, after.y - before.y) > reach
