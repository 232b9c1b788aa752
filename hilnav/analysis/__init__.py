"""``hilnav analyze``: what a log allows to conclude (errors, drift, map, boxes) and its plots."""
