"""The closed pads as a pusher: where they start and where their tips push, for the
planner's strikes and sweeps and for the bring-up that chooses which pushes to ask for.

Both read these constants, so the pushes the bring-up plans are the pushes the planner
makes; were they planner parameters, changing one on the running planner node would
leave the bring-up planning with the old value.
"""

from __future__ import annotations

PUSHER_STANDOFF = 0.01  # m between the pads and the pushed domino's back face before a push
SWEEP_HEIGHT = 0.4  # of a swept domino's vertical extent, where the fingertips push
MAX_SWEEP_DISTANCE = 0.1  # m a sweep may push a domino (two lengths)
PADS_HALF = 0.008  # m: half the closed pads (~16 × 16 mm) along the push
