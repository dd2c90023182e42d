"""The dynamic model: masses, springs and dampers in time (`dynamic`), its element geometry
(`dynamic_geometry`) and compiled inner loop (`kernels`), the Newmark integration
(`newmark`), natural frequencies (`modes`), simulation of a prescribed motion
(`simulation`) and the excitation frequencies (`excitations`).

May import: `base`, `laws`, `reducer`, `statics`, `losses`.
"""
