"""The ground floor of the Robotarium testbed: what the simulator, the safety node, the recorder
and the client share. Plain modules (`model`, `config`) import no ROS; `topics`, `parameters`,
`node_main`, `dds_settings` and `dds_health` are the ROS side every node uses the same way. No
nodes live here, and nothing here imports the project's other packages."""
