"""fusion layer of hilnav (see DESIGN.md)."""
