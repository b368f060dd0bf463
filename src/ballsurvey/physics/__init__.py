"""Jitted physics of the rolling biased ball (non-dimensional): Euler-angle and fixed-frame forms,
invariants, contact forces, steady circles."""
