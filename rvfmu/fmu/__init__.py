"""The reducer as an FMI 2.0 or 3.0 co-simulation FMU: a thin adapter over the core."""
