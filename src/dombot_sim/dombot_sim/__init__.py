"""Drake simulation of the DOM-BOT cell exposed over ROS 2 like real hardware: cameras, joint
states, trajectory and gripper actions.
"""
