"""MCAP logs: writer (with Foxglove views), reader, info, recovery, replay and analysis."""
