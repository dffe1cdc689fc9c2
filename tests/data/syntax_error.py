"""A script that does not compile: a colon is missing on line 6."""
import numpy as np

import rps.robotarium as robotarium

for k in range(3)
    print(k)
