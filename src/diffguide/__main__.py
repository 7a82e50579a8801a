"""``python -m diffguide``: the command line (as the ``diffguide`` script)."""

from .cli import console_main

console_main()
