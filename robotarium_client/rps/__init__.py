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
