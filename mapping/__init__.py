"""mapping layer of hilnav (see DESIGN.md)."""
