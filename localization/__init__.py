"""localization layer of hilnav (see docs/architecture.md)."""
