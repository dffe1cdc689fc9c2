"""Recording of Robotarium runs: bag I/O (`bag`), the recorder and replay nodes, and the results
of a run made from its bag alone (`results`)."""
