"""The simulator skips the arm's contacts with itself (the planner keeps it clear of
itself) and nothing that can meet a domino or the table."""

from __future__ import annotations

from pydrake.geometry import GeometryId, Role

from dombot_sim.world import CellWorld, WorldConfig


def test_the_arm_is_not_checked_against_itself_but_the_fingers_and_the_table_are() -> None:
    world = CellWorld(WorldConfig(cameras=False, domino_capacity=1))
    inspector = world._scene_graph.model_inspector()
    ids = inspector.GetAllGeometryIds(Role.kProximity)

    def of(frame_name: str) -> list[GeometryId]:
        return [g for g in ids if inspector.GetName(inspector.GetFrameId(g)).endswith(frame_name)]

    upper_arm, forearm = of("iiwa_link_2"), of("iiwa_link_5")
    gripper, finger = of("wsg_body"), of("wsg_left_finger")
    table, domino = of("table_top"), of("domino_0::domino")
    assert upper_arm and forearm and gripper and finger and table and domino

    def filtered(a: list[GeometryId], b: list[GeometryId]) -> bool:
        return all(inspector.CollisionFiltered(x, y) for x in a for y in b)

    assert filtered(upper_arm, forearm) and filtered(upper_arm, gripper)
    assert not any(inspector.CollisionFiltered(x, y) for x in finger for y in upper_arm)
    for part in (upper_arm, forearm, gripper, finger):
        assert not filtered(part, table) and not filtered(part, domino)
