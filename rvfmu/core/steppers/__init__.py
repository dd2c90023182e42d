"""The reducers a host steps in time, as the FMUs' `model` parameter names them: the TE map
(`te_map`), the quasi-static reducer over it (`reducer_model`), the dynamic reducer
(`dynamic_reducer`, and `compile_kernels` for the FMU to bundle) and both by name
(`reducers`).

May import: every other room.
"""
