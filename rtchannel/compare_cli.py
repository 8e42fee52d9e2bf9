"""`rtchannel compare` (placeholder)."""


def add_compare(sub) -> None:
    """Register the `compare` subcommand."""
