"""python -m robotarium_cli VERB ...: the robotarium command."""
from robotarium_cli.main import console_main

console_main()
