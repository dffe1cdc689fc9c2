"""The ground floor of the Robotarium testbed: what the simulator, the safety node, the recorder
and the client share. Plain modules (`model`, `config`) import no ROS; `topics` and `node_tools`
are the ROS side every node uses the same way. No nodes live here."""
