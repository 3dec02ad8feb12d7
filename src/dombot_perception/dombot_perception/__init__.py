"""RGB-D perception of a domino pile: segmentation, multi-camera box fitting, grasp scoring;
publishes domino poses.
"""
