"""python -m graindyn: the command line."""
from .cli import main

main()
