"""The 2.x toolbox (`rps.utilities` in 2.x scripts): transformations, controllers, barrier
certificates, misc, graph, as in the Robotarium Python simulator 2.1.0."""
