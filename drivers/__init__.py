"""drivers layer of hilnav (see DESIGN.md)."""
