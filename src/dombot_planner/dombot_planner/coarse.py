"""Coarse moves by Drake's KinematicTrajectoryOptimization on a shadow-plant scene.

Between two joint configurations found by IK (so both end poses hold exactly): a cubic
B-spline with zero velocity at both ends, joint limits, minimum-distance constraints at
evenly spaced samples and a path-energy cost. Attempts differ in their initial guess:
the straight joint-space line, then a via configuration raised above both ends (the
paper's intermediate pose between pile and run), then random perturbations of it; later
attempts sample collisions more densely.
"""

from __future__ import annotations

import numpy as np
from pydrake.multibody.inverse_kinematics import MinimumDistanceLowerBoundConstraint
from pydrake.planning import KinematicTrajectoryOptimization
from pydrake.solvers import SnoptSolver, SolverOptions
from pydrake.trajectories import BsplineTrajectory

from dombot_planner.ik import PoseIK
from dombot_planner.scene import Scene

INFLUENCE_OFFSET = 0.02  # m beyond the bound where distances start to shape the constraint
VIA_LIFT = 0.15  # m the via configuration's TCP rises above the higher end
SNOPT_MAJOR_ITERATIONS = 300


def initial_guess(
    scene: Scene,
    q_start: np.ndarray,
    q_goal: np.ndarray,
    attempt: int,
    points: int,
    rng: np.random.Generator,
) -> np.ndarray:
    """Control points (n × points) of the initial guess for ``attempt``."""
    if attempt == 0:
        return np.linspace(q_start, q_goal, points).T
    via = raised_via(scene, q_start, q_goal)
    if via is None:
        via = (q_start + q_goal) / 2.0
    if attempt >= 2:
        lower, upper = scene.plant.GetPositionLowerLimits(), scene.plant.GetPositionUpperLimits()
        via = np.clip(via + rng.normal(0.0, 0.3, via.shape), lower, upper)
    half = points // 2
    first = np.linspace(q_start, via, half, endpoint=False)
    second = np.linspace(via, q_goal, points - half)
    return np.vstack([first, second]).T


def raised_via(scene: Scene, q_start: np.ndarray, q_goal: np.ndarray) -> np.ndarray | None:
    """IK of the TCP midway between both ends, VIA_LIFT above the higher one."""
    start, goal = scene.tcp_pose(q_start), scene.tcp_pose(q_goal)
    middle = (start.translation() + goal.translation()) / 2.0
    middle[2] = max(start.translation()[2], goal.translation()[2]) + VIA_LIFT
    seed = (q_start + q_goal) / 2.0
    return PoseIK(scene, goal.rotation()).solve(middle, seed, seed)


def optimize(
    scene: Scene,
    q_start: np.ndarray,
    q_goal: np.ndarray,
    guess: np.ndarray,
    bound: float,
    samples: int,
) -> BsplineTrajectory | None:
    """One KTO solve (normalised duration 1; TOPP-RA retimes it); None if SNOPT fails."""
    plant = scene.plant
    points = guess.shape[1]
    trajopt = KinematicTrajectoryOptimization(plant.num_positions(), points, 4, 1.0)
    prog = trajopt.get_mutable_prog()
    trajopt.AddDurationConstraint(1.0, 1.0)
    trajopt.AddPathEnergyCost(1.0)
    trajopt.AddPositionBounds(plant.GetPositionLowerLimits(), plant.GetPositionUpperLimits())
    trajopt.AddPathPositionConstraint(q_start, q_start, 0.0)
    trajopt.AddPathPositionConstraint(q_goal, q_goal, 1.0)
    zero = np.zeros(plant.num_velocities())
    trajopt.AddPathVelocityConstraint(zero, zero, 0.0)
    trajopt.AddPathVelocityConstraint(zero, zero, 1.0)
    collision = MinimumDistanceLowerBoundConstraint(
        plant, bound, scene.plant_context, None, INFLUENCE_OFFSET
    )
    for s in np.linspace(0.0, 1.0, samples)[1:-1]:
        trajopt.AddPathPositionConstraint(collision, s)
    trajopt.SetInitialGuess(BsplineTrajectory(trajopt.basis(), guess))
    options = SolverOptions()
    options.SetOption(SnoptSolver.id(), "Major iterations limit", SNOPT_MAJOR_ITERATIONS)
    result = SnoptSolver().Solve(prog, None, options)
    if not result.is_success():
        return None
    return trajopt.ReconstructTrajectory(result)
