"""``hilnav replay``: a log's device messages through the services again, deterministically."""
