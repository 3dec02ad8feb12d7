"""The arm job's settings: every bound of the task policy, with the reasons behind it."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from dombot_bringup.layouts import MAX_SPACING_RATIO, MIN_SPACING_RATIO
from dombot_description import DOMINO_SIZE


@dataclass(frozen=True)
class ArmJobSettings:
    pile: int = 30  # dominoes poured
    seed: int = 0
    max_attempts: int = 4  # per domino: perceive, plan, carry and place
    # ... and picks that failed before anything was carried (missed, blocked): they leave
    # the run as it was and stir the pile. S-curve seed 3 stopped after 4 misses in a row
    # at its last gap with 16 dominoes still detected in the pile.
    max_missed_picks: int = 8
    # Per attempt, dominoes offered to the planner with their pile until one plans, then
    # the roomiest with their pile's cores (the pads may reach into a neighbour's box but
    # not its core; the gripper body keeps clear of the box), then ignoring the pile
    # (unless the slot can be put off instead).
    # Ignoring it, 6 of 12 picks failed; replayed, each of the 6 had the pads'
    # path 3.3-7.7 mm deep in a detected neighbour, the 6 that held at most 2.9 mm.
    max_candidates: int = 16
    last_resort_candidates: int = 3
    # m per side a neighbour's core is smaller than its box: the planner keeps the pads'
    # path 1.5 mm (pile_point_clearance) from the core, so ~3 mm deep in the box at most.
    pile_core_shrink: float = 0.0045
    # ... and when nothing plans with the cores either, a pile domino is pushed out of its
    # crowd (``spread``) and the pile looked at again, at most max_spreads times a slot,
    # before the pile is ignored: the shortest push after which nothing seen lies within
    # spread_clearance of its long sides (perception's scoring caps its clearance at
    # 15 mm), its centre within spread_radius of the pile's centre (the cameras see 0.16 m
    # around it); the roomiest first, asking the planner at most spread_plans times; when
    # none of those plans (the pile is jammed), a push through the neighbours
    # (``spread.stir_pushes``), as many times at most.
    max_spreads: int = 2
    # When only a pick ignoring its pile plans, that domino (a grasp reaches it, the pads
    # only through a neighbour) is pushed out of its crowd first (or through it, when no
    # push keeps clear), the pile looked at again and the attempt starts over, at most
    # max_isolations times a slot (``clearing.isolate``); such pushes cost no attempt.
    # Ignoring their pile, 7 of 10 picks in two 30-domino runs closed on nothing: the pads
    # landed on a neighbour (the approach ended short of its grasp) or went through one.
    # 0: picked ignoring its pile at once, as before.
    max_isolations: int = 2
    # Before spreading, a pile domino no grasp takes as it lies (on its edge: no grasp of
    # the family holds it; or refused even ignoring its pile) is pushed over, or
    # slid towards the pile's centre (``clearing.lay_flat``), at most max_lay_flat times a
    # slot; such pushes cost no attempt. (A 45-domino pile once ended with every
    # remaining domino refused, the run at 29 of 30; dominoes on an edge were never
    # offered.)
    max_lay_flat: int = 4
    # A leaning pile domino that plans is pushed over flat first (``clearing.lay_leaning_flat``,
    # within max_lay_flat), the pile looked at again: 4 of 22 leaning picks in four runs
    # failed (the fingers met an edge, or closed on nothing), no pick of a flat one that
    # planned with its pile or its cores (35). When no push plans, a flat domino offered
    # after it is picked if one plans (``attempts.flat_instead``). False: picked as it leans.
    lay_leaning_flat: bool = True
    # A slot that cannot be put off any more, whose place the planner refused
    # (PLACE_UNREACHABLE) for this many flat pile dominoes in one attempt and nothing else
    # (bar GRASP_UNREACHABLE, which says nothing of the slot), is given up at once: a flat
    # domino is held by the canonical grasp, so every other flat one, and every one a push
    # lays flat, gets the same refusal. (A safety gap between two standing neighbours on a
    # spiral's tight curve spent 4 attempts, 2 spreads and 4 lay-flat pushes, ~10 min
    # wall, before it was left empty.) Only when the last of them is refused with its pile
    # ignored too: a crowded pile may leave a pick only holds that do not reach the slot
    # (attempts.places_ignoring_pile). 0: never; its attempts are spent as before.
    give_up_unplaceable: int = 3
    spread_clearance: float = 0.016  # m
    spread_radius: float = 0.13  # m
    spread_plans: int = 6
    pile_center: tuple[float, float] = (0.55, -0.30)  # m, the scenario's pile_area
    # Placing at a slot this far from the pile's centre, the arm leaves perception's look
    # at the pile as it is with the arm at home, so the next pick's look at the pile is
    # asked for as the carry ends above the slot (before the hand check, which perception
    # serves beside it) and made while the arm holds the domino there and places it.
    # Rendered in Drake with the arm where the carry ends, down the descent, at the release
    # and where the retreat ends (benchmarks/bench_pile_view.py, docs/SPEED.md): camera_0
    # and camera_1 lost no pile pixel at any slot 0.20-0.36 m from the centre (the arm
    # comes from the far side of the pile). At 0.20-0.21 m the slot's domino and the hand
    # lie in perception's pile region (0.21 m around the centre, up to 0.07 m): it is
    # detected there as a pile domino, the hand's points are obstacles; from 0.22 m on,
    # the same detections and scene points as with the arm at home. 0.235 m: the S-curve's
    # first slot, 15 mm beyond. 0.32 m left the S-curve's slots 1-3 with no look while
    # placing (and nothing planned ahead for slots 2-4).
    look_while_placing: float = 0.235  # m
    # Ask for the next slot's first pick as a domino starts down to its slot, or once the
    # pile look answers while it is placed (``ahead``): the planner then plans on the other
    # core while the arm places and retreats and perception checks the placement. False:
    # asked once the check answered.
    plan_ahead: bool = True
    # A pick whose every grasp the planner would refuse before any IK (the pads' path on
    # seen points, the pads beyond its pile_nudge in a pile domino, the wrist beyond the
    # elbow's reach, a turned grasp's hold with no place pose: the planner's own tests,
    # ``dombot_planner.foreseen_refusal``) is taken
    # as refused without asking it (``picking.foreseen``), and not asked ahead. False:
    # every offer is asked.
    foresee_refusals: bool = True
    section: int = 4  # dominoes between safety gaps, which are filled last (0: run order)
    # Before the build, the planner is asked to place a flat pile domino at each safety
    # gap's last slot between its standing neighbours (``task.gaps``), with at most this
    # many dominoes when their grasps are refused (0: not asked, the gaps as laid out).
    # Refused its place, the gap moves up to gap_moves slots either way to where it plans,
    # else it is dropped: s_curve30 at 22 mm refused every gap's last slot (each planned
    # with one neighbour) and left all four empty.
    gap_probe_dominoes: int = 3
    gap_moves: int = 1
    # A slot put off whose next turn would come between two standing neighbours: the
    # planner is asked the same with at most this many flat dominoes (``task.enclosure``);
    # refused, the slot's last turn comes before its second neighbour is built (0: not
    # asked, put off as any other: s_curve30's first 10 at 22 mm put slot 3 off, built the
    # 4th, then spent a turn behind each later slot on a place refused between the two).
    enclosure_probe_dominoes: int = 3
    # Where neighbours stand closer than order_probe_spacing (the pads of a hold leaning
    # over one come within 2 mm of it: at 24 mm 1.1 mm, at 26 mm 2.9 mm on a straight run,
    # less on a curve's inner side), the planner is asked before the build, with at most
    # this many flat dominoes, which slot of each stretch to start from (``task.order``):
    # the s-curve of 10 at 22 mm refused slots 2-4 with the one behind standing, each of
    # which plans with the one ahead (0: not asked, run order).
    order_probe_dominoes: int = 3
    order_probe_spacing: float = 0.027  # m between neighbouring centres
    plan_budget: float = 5.0  # s of planning per request
    # s simulated from letting go to checking a placement: in the simulator's truth
    # released dominoes were at rest (asleep) 0.01-0.17 s after the fingers let go (4 of
    # an arc), or rocked within 0.1 mm of where they stayed, at 0.25 s as at 0.5 s
    # (tests/bringup/test_sim_cell.py). The retreat (~0.3 s) takes its share; 0.5 s had
    # the arm wait ~0.2 s a domino after it.
    settle_after_place: float = 0.25
    topple_wait: float = 3.0  # s simulated after the strike
    # Times what perception still sees standing after the strike is struck again, as
    # sections from where it stands (a domino kept 10 mm off its target broke the chain;
    # arc10_cycles5 seed 3's first cycle then failed with its last domino standing)
    strike_again: int = 2
    place_tolerance: float = 0.003  # m, perception's check
    place_tilt_tolerance: float = math.radians(3.0)
    # An upright domino up to this far off its target stays where it stands (it still
    # topples the next; spacing is ~60 % of its height): lifting it out of the run again is
    # where cascades started (a re-pick 4.4 mm off knocked four standing ones). 0: re-pick.
    keep_off_target: float = 0.006  # m
    # ... and up to this far off once picking it up again failed: it blocks its own slot
    # (S-curve seed 4: one stood 8.9 mm off, both re-picks missed, and every place for its
    # slot was refused for ever). 12 mm off, the next still stands within the toppling range.
    keep_when_stuck: float = 0.012  # m
    # A run domino (not the one just placed) seen still standing but beyond those bounds,
    # or leaning more than place_tilt_tolerance, is looked at again (fresh frames, a
    # camera period on); confirmed, it stays where it stands while the run still topples
    # through it (``chain.chain_breaks``): the centres' spacing along the fall within
    # chain_spacing of the height (the layouts' range: every simulated wave from 30 % to
    # 90 % carried, docs/SIM_WAVE.md), the next's centre off the line of the fall by at
    # most (1 - chain_min_overlap) of the width, their faces turned at most chain_max_yaw,
    # and it leaning at most chain_max_tilt (beyond, it does not stand on its own foot).
    # (circle30 seed 1: one read 7.8 mm and 7.3° off was picked as fallen from between
    # two standing neighbours, and the 18 before it fell.)
    chain_spacing: tuple[float, float] = (MIN_SPACING_RATIO, MAX_SPACING_RATIO)
    chain_min_overlap: float = 0.5
    chain_max_yaw: float = math.radians(30.0)
    chain_max_tilt: float = math.atan2(DOMINO_SIZE[2], DOMINO_SIZE[0])
    # ... and where the run would stop at it, it is picked up again only when at most this
    # many standing dominoes stand with no empty slot between them and it (a fall would
    # take them down: a section between open safety gaps has section - 1 others); in a
    # longer stretch it is left standing, and the risk told (-1: always left).
    replace_risk: int = 3
    # Released dominoes end up behind the pose they were released at, along the run: by
    # 0.75 mm on average in truth (sd 0.6-1.0 mm; 170 placements, arc and S-curve alike):
    # ~0.45 mm from the grasp, the rest as the pads let go. The arm releases them this much
    # ahead (the check still measures from the target).
    place_lead: float = 0.00075  # m
    # Straight above its slot, before the descent, perception looks at the held domino:
    # one whose foot is this far from where it should be held there, or that leans this
    # much, turned or slid in the hand on the way (the off placements seen with sim_node's
    # motion log did: 2.1 mm / 5.4° in the hand, 3.4 mm off once let go) and is carried
    # again from there, once. (Looked at on its slot, a correction carried it out from
    # between its standing neighbours: twice it left the fingers and knocked them over.)
    # 0: no check (it costs a camera frame and the fits, ~1 s simulated per domino).
    # With nothing wrong the foot reads ~1 mm off (rendered holds; median 1.35 mm over the
    # benchmark's readings), the tilt within 0.2°.
    in_hand_tolerance: float = 0.002  # m
    in_hand_tilt_tolerance: float = math.radians(1.5)
    # ... or that hangs this much lower than planned (slid down in the fingers) is carried
    # again as held, once: the place line ends release_height (0.2 mm) above the table for
    # the hold as planned, so the descent would press a lower one into the table. At 22 mm
    # (37 holds read) a descent lagged ~3e-3 rad per mm read low; 1 mm is beyond 35 of the
    # 37. Perception reads a low hold 0.4-0.5 mm short; a higher one reads as planned (the
    # fit has nothing to pull its box up), so hanging higher is not judged.
    in_hand_low_tolerance: float = 0.001  # m
    # Not seen there (the gripper, leaning over the run's free side, hides the part below
    # the pads from every camera: s_curve30 slots 21-23 at every turn in the hand), a hold
    # whose fall could take down more than in_hand_look_risk standing dominoes (no empty
    # slot between; a section between safety gaps has at most section - 1) is looked at
    # again with the arm's base joint turned in_hand_look_turn, at most in_hand_look_speed,
    # and turned back: arm and hold turn rigidly about the base's vertical axis, at the
    # carry's height (the foot 22 mm above the run's tops), and a camera sees the part
    # below the pads past the gripper (benchmarks/bench_in_hand_planned.py --looks;
    # PERCEPTION_MEASURED.md). A blind placement failed 15 % of the time in the ledger runs
    # (2.7 % after a look that saw the hold), one in s_curve30 felling 27. The look costs its
    # turns (1.65 s simulated at -15°) and a camera frame. 0: no second look.
    in_hand_look_turn: float = math.radians(-15.0)
    in_hand_look_speed: float = 0.5  # rad/s
    in_hand_look_risk: int = 3
    # However far it turned: placed as held, a domino leaning more than ~9° (its thickness
    # over its height) cannot stand. The two holds read 12.1° and 12.2° off in a
    # benchmark were placed as held (the bound was 12°) and fell, one at a
    # safety gap taking four standing neighbours with it; a correction from above the slot
    # placed one read 10.8° off 0.8 mm from its target.
    # A foot read farther off than this is taken as a misreading: pinched at its top and
    # turned 12°, the foot moves ~7 mm (35 mm of lever), plus what the hold slides
    # (≤ 5.4 mm read in the benchmarks). One read 13.1 mm off at 1.5°
    # in a stale frame (now refused: not_before), whose hold the simulator had shifting
    # 1.1 mm / 1.2°, was "corrected" 12.9 mm off; at 6 mm a real 6.2 mm / 3.9°
    # shift was refused and the domino stood 7.1 mm off.
    in_hand_max_off: float = 0.012  # m
    # A hold leaning more than this whose correction the planner refused is not placed
    # (it would fall, at a safety gap onto standing neighbours: an S-curve run,
    # 12.3°) but carried back over the pile and dropped there: the ~8.9° at
    # which a domino's weight leaves its foot (thickness over height). Not less: carried
    # back, a loose hold read 8.3° slipped out over the run and felled four.
    put_back_lean: float = math.atan2(DOMINO_SIZE[2], DOMINO_SIZE[0])
    grasp_width_tolerance: float = 0.003  # m: fingers stopped this close to the domino width
    # ... but not this much inside it: a flat hold stops 0.2-0.8 mm inside (the pads' give
    # at grip_force); 0.9 mm and more inside, the pads met an edge and the domino hangs
    # tilted (both such grasps seen fell when released; rejected, the domino drops back).
    grasp_squeeze_limit: float = 0.00085  # m
    # An approach that ends this close to its grasp pose (rad per joint; the simulator's
    # default is 0.01) closes the gripper and lets the grasp check judge: the gripper body
    # resting 0.1 mm deep on a pile domino stopped joint 6 0.012 rad (~1.5 mm) short.
    approach_goal_tolerance: float = 0.02  # rad
    # The descent to a place stops when a joint falls this far behind it (0: never), and
    # the domino goes back to the pile: one pressing on something (a carry again from an
    # off hold stalled 0.0128 rad short at joint 6 and pushed its neighbour over at
    # 22 mm). A free descent's largest tracking error is ~1.5e-3 rad; descents of pile
    # dominoes hanging low pressed the table 4.8-9.3e-3 rad behind and, let go, mostly
    # stood (at 5e-3 the s-curve's 8th slot was given up after four stops): those go on.
    place_path_tolerance: float = 0.012  # rad
    # The fingers open for a grasp as the arm starts its move to above it (planned with
    # them open) when they stand this close to that opening: after a let-go (release
    # opening, 6 mm narrower; the fingers stop within 1 mm of it, 33.4 mm seen) each pad
    # starts up to 3.5 mm inside where the plan has it, within the 5 mm the planner's
    # coarse moves keep from everything (coarse_clearance). Farther (as poured at the
    # start, closed after a strike) they open first, the arm still. 0: always first.
    open_while_moving: float = 0.007  # m
    # Fallen dominoes no grasp reaches, lying within a domino length of the slot to build
    # (debris of a cascade, wedged between standing neighbours), are pushed across the
    # run until they lie this far beyond its side; at most max_sweeps per slot (a sweep
    # carrying a blob along may leave another of it in the way: arc cycles seed 3's slot 5
    # had two, then burnt its last attempts on a domino the next slot's first sweep moved).
    sweep_margin: float = 0.008  # m
    max_sweeps: int = 4
    # A slot whose way is still blocked when no pick or sweep of what lies there plans
    # (pads and pusher too near its standing neighbours) has a standing neighbour picked
    # up and stood beside the pile (``staging.set_aside``), at most max_set_asides times
    # a slot (0: never); the neighbour's slot is built again after it. The spot is on the
    # circle staging_ring about the pile's centre (inside perception's pile region, 0.21 m),
    # its footprint staging_clearance from every domino and point seen there.
    max_set_asides: int = 2
    staging_ring: float = 0.14  # m
    staging_clearance: float = 0.03  # m
    # The lying dominoes on a sweep's way are pushed along with it (``debris.carried_along``:
    # a shingled row as one blob), unless one of them lies within carry_clearance of a
    # standing domino before or after the push, or would be pushed into one; then the
    # sweep keeps clear of every lying domino (as before the blob). Dragged, one may turn:
    # in arc cycle 5 one pushed along moved 30 mm and turned 50°, and a standing domino
    # 6 cm from the swept one was left leaning 9° (picked up and built again): how far a
    # dragged domino may go is not measured; 5 mm is the planner's coarse_clearance.
    carry_clearance: float = 0.005  # m
    # A domino lying (fallen, or toppled by an earlier cycle) whose footprint comes within
    # clear_margin of a slot's domino (perception located a struck run's dominoes within
    # 7.6 mm), or within clear_pads more across the run (the pads beside it: release
    # clearance and pad thickness), is in that slot's way: nothing is placed there until it
    # is gone, taken as the slot's domino or swept aside (``picking.in_its_way``). A
    # placement beside a toppled domino knocked three standing ones down (arc, cycle 3).
    clear_margin: float = 0.008  # m
    clear_pads: float = 0.013  # m
    # A struck domino perception sees down but cannot fit is taken to lie tipped this far
    # over the front edge of its foot (``tipped_pose``; flat: the farthest it reaches
    # ahead): an obstacle and in the way of the slots it covers, swept, never picked.
    unfitted_lean: float = math.pi / 2  # rad from vertical
    real_time_factor: float = 1.0
    camera_rate: float = 2.0
    meshcat: bool = False  # show the cell in Meshcat; keep it up at the end until Enter
    # --record: every topic into OUT/run.mcap (raw images thinned to this rate, Hz) and
    # Meshcat's recording into OUT/scene.html
    record: bool = False
    record_image_rate: float = 1.0
    foxglove_port: int | None = None  # serve the topics live to Foxglove here
    # a folder for each executed pick's record: what was offered and planned, and the
    # simulator's truth then (benchmarks/replay_pick.py replays it); None: not recorded
    record_picks: Path | None = None
