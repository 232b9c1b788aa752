"""``hilnav import``: public data sets written as hilnav MCAP logs."""
