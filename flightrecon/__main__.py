"""``python -m flightrecon``: the command line (same as the ``flightrecon`` script)."""

from flightrecon.cli.entry import run

run()
