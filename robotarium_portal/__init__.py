"""The Robotarium as a service for a class: accounts, experiments, verification, the queue and results in
the browser (Django; django-q2 for the verification and run jobs). `./robotarium serve` starts it."""
