"""The losses: the contacts' friction, efficiency, running and starting torque
(`friction`), the lubricant's churning (`churning`) and the hysteresis loop of the
catalogue's windup test (`hysteresis`).

May import: `base`, `laws`, `reducer`, `statics`.
"""
