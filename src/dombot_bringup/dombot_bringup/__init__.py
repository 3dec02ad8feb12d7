"""Bring-up of the DOM-BOT node graph: builds a domino run from a pile in simulation and
knocks it down.
"""
