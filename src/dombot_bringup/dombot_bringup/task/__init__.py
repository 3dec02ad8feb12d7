"""The arm job's task policy, without ROS: build a layout from the pile through a ``Cell``.

Modules, each one job (docs/ARCHITECTURE.md, "Task core modules"):
``cell`` the Cell protocol and its plain types; ``loop`` the slot loop; ``attempts`` one
attempt at a slot; ``picking`` candidates and offers to the planner; ``placing`` running
a plan, the in-hand check; ``clearing`` sweeps, spreads and stirs; ``checks`` placement
checks; ``strike`` the knock-down; ``records`` report truth, pictures, pick records;
``state`` the run's state; ``geometry`` spots and distances; ``settings`` the bounds.
"""
