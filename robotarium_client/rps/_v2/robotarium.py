"""`import rps.robotarium as robotarium` for 2.x scripts: the 2.x Robotarium on the ROS 2 testbed."""
import math  # noqa: F401
import time  # noqa: F401

import numpy as np  # noqa: F401

from robotarium_client.robotarium2 import Robotarium  # noqa: F401
