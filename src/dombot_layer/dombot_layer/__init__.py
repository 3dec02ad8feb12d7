"""Domino-laying vehicle: exact trolley kinematics, wheel velocity commands, path schedules
and a vehicle simulation.
"""
