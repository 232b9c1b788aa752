"""localization layer of hilnav (see DESIGN.md)."""
