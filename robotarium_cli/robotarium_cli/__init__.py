"""The robotarium command (`robotarium VERB`, `./robotarium VERB`, `ros2 robotarium VERB`): one module
per verb in robotarium_cli.verb; console (messages, signals, argument types), folders (run folders
and results), running (a script run against a testbed), runner (the script's own process),
verification (the Robotarium's rules)."""
