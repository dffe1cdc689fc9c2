"""The Robotarium Python API (`rps`) on ROS 2.

The same import path as the Robotarium's own simulator (PyPI robotarium-python-simulator), so
that experiment scripts written for it run unchanged:

    import rps.robotarium as robotarium
    from rps.utilities.transformations import *
    from rps.utilities.graph import *
    from rps.utilities.barrier_certificates import *
    from rps.utilities.misc import *
    from rps.utilities.controllers import *

`rps.robotarium.Robotarium` talks to the testbed over DDS; `rps.utilities` is the researcher's
toolbox (plain numpy; only `misc` touches matplotlib).
"""
import os as _os
import sys as _sys

from robotarium_client import api_level as _api_level
from robotarium_client import session as _session

# The guide's API or the simulator 2.x's, decided once, when a script first imports rps (see
# robotarium_client.api_level). For 2.x, the 2.x modules (rps/_v2/, under the same names) come first.
API, API_REASON = _api_level.decide(_session.options.rps_api)
if API == _api_level.V2:
    __path__.insert(0, _os.path.join(_os.path.dirname(__file__), "_v2"))
    print("[robotarium] Robotarium simulator 2.x API: %s (./robotarium run --rps guide to change)" % API_REASON,
          file=_sys.stderr)
