"""`import rps.robotarium as robotarium` gives the Robotarium class of this stack (over ROS 2).

As in rps, the module also carries numpy (np), math, time and the misc utilities, which some
scripts reach through it.
"""
import math  # noqa: F401
import time  # noqa: F401

import numpy as np  # noqa: F401

import rps.utilities.misc as misc  # noqa: F401
from robotarium_client.robotarium import Robotarium  # noqa: F401
