"""mapping layer of hilnav (see docs/architecture.md)."""
