"""flightrecon.store: per-aircraft coefficient store."""
