"""fakes layer of hilnav (see DESIGN.md)."""
