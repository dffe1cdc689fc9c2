"""Barrier certificates (plain numpy + OSQP: barrier_certificates) and the safety node."""
