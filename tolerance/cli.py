"""`rvte mc` and `rvte sobol`: registered on the `rvte` parser by `add_study_commands`."""


def add_study_commands(subparsers) -> None:
    """Add the tolerance-study sub-commands to the `rvte` sub-parsers."""
