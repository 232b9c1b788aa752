"""Errors the user can fix (bad config, bad port): printed as one clear line by the CLI."""


class CliError(Exception):
    """An error the user can fix: printed as one line, exit code 2."""
