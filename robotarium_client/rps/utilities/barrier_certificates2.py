"""Robust barriers (guide section 4.6): the rps import path for robotarium_safety's.

create_robust_barriers lives in robotarium_safety/robotarium_safety/barrier_certificates.py;
this module re-exports it under rps's module name. rps's barrier_certificates2 also exposed
`np` and `time` (and its solvers' cvxopt/quadprog objects, which this stack does not use), so a
star import here brings `np` and `time` as well.
"""
import time

import numpy as np

from robotarium_safety.barrier_certificates import create_robust_barriers

__all__ = ["np", "time", "create_robust_barriers"]
