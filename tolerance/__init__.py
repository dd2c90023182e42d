"""Tolerance studies: sampling manufacturing errors, Monte Carlo, Sobol ranking, allocation."""
