"""Numba integrators: Butcher tableaus, the ensemble kernel, the naive baseline."""
