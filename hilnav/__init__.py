"""hilnav application layer: configuration, daemon, Zenoh bus, MCAP log, CLI (layer 4)."""

__version__ = "0.1.0"
