"""fakes layer of hilnav (see docs/architecture.md)."""
