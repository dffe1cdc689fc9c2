"""The `rps` import path as the Robotarium Python simulator 2.x has it (2.1.0, MIT licence).

Not imported by this name: when a script is recognised as a 2.x script (robotarium_client.api_level),
`rps/__init__.py` puts this folder first on `rps.__path__`, so that `import rps.robotarium` and
`from rps.utilities.controllers import ...` find the 2.x modules here, with 2.x's names, signatures
and defaults, while guide scripts keep the guide's `rps`. The modules are written anew from
2.1.0's documented behaviour (see each module); where we differ, the module says so and why.
"""
