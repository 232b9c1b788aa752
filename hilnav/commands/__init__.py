"""Sub-commands of the ``hilnav`` CLI, one module each (see ``hilnav.cli``)."""
