"""Robot, gripper, table, domino and camera models and the one scenario file the DOM-BOT
simulator and planner both load.
"""
