"""The element laws and the estimates from geometry: the pins' Hertz law (`pin_law`), the
roller bearings' law (`roller_law`), the element compliances (`compliance`), the stiffness
estimates the seeds do not give (`stiffness`), the lubricant's viscosity (`lubricant`) and
the seals' friction law (`seals`).  Each law is a function of its element's numbers, not of
a reducer.

May import: `base`.
"""
