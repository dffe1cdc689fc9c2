"""Barrier certificates (guide section 4.5): the rps import path for robotarium_safety's.

The certificates themselves (QP with OSQP, no ROS) live in
robotarium_safety/robotarium_safety/barrier_certificates.py, where the safety node uses them
too; this module only re-exports them under rps's names, so that
`from rps.utilities.barrier_certificates import *` works as in the guide's scripts. Like rps's
module, it also brings `np` and the transformations (rps star-imports them there).
"""

from robotarium_safety.barrier_certificates import (
    # Short aliases (older rps releases and the MATLAB toolbox use these names).
    create_si_barrier_certificate,
    create_si_barrier_certificate_with_boundary,
    create_single_integrator_barrier_certificate,
    create_single_integrator_barrier_certificate2,
    create_single_integrator_barrier_certificate_with_boundary,
    create_uni_barrier_certificate,
    create_uni_barrier_certificate_with_boundary,
    create_unicycle_barrier_certificate,
    create_unicycle_barrier_certificate2,
    create_unicycle_barrier_certificate_with_boundary,
    create_unicycle_differential_drive_barrier_certificate,
    create_unicycle_differential_drive_barrier_certificate_with_boundary,
)
from rps.utilities.transformations import *  # noqa: F401,F403 (rps's module brings them too)
from rps.utilities.transformations import __all__ as _transformations_all

__all__ = list(_transformations_all) + [
    "create_single_integrator_barrier_certificate",
    "create_single_integrator_barrier_certificate_with_boundary",
    "create_single_integrator_barrier_certificate2",
    "create_unicycle_barrier_certificate",
    "create_unicycle_barrier_certificate_with_boundary",
    "create_unicycle_barrier_certificate2",
    "create_unicycle_differential_drive_barrier_certificate",
    "create_unicycle_differential_drive_barrier_certificate_with_boundary",
    "create_si_barrier_certificate",
    "create_si_barrier_certificate_with_boundary",
    "create_uni_barrier_certificate",
    "create_uni_barrier_certificate_with_boundary",
]
