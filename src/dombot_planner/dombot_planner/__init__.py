"""The /plan_place service: pick-and-place trajectories by Drake kinematic trajectory
optimization on a shadow plant.
"""
