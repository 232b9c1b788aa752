"""MCAP logs: writer (with Foxglove views), reader, info and recovery of truncated files."""
