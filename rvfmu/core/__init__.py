"""The physics of rvte: an RV reducer, its errors, its statics, losses and dynamics.

It knows nothing of files but the design and error files it reads, nothing of plots, FMI or
studies; the CLI, the FMUs and `tolerance` are layers over it.  Its rooms, each of which may
import only the rooms before it (tests/test_layering.py holds that, function-level imports
included, and that no module imports itself in a circle):

1. `base`: units, input checks and numba's `kernel`, which every room uses;
2. `laws`: the element laws and the estimates from geometry (pins, roller bearings,
   compliances, stiffness estimates, lubricant, seals);
3. `reducer`: the reducer and its errors (design, presets, disc profile, errors, limits);
4. `statics`: the quasi-static model (equivalent model, Newton iteration and its kernel,
   solver, TE curves and windup, metrics, the independent reference, the compliance budget);
5. `losses`: friction, churning and the hysteresis loop;
6. `dynamics`: the dynamic model (its geometry and kernels, Newmark, modes, simulation,
   excitations);
7. `steppers`: the reducers a host steps in time (the TE map, the quasi-static and dynamic
   reducer models).
"""
