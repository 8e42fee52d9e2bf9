"""`rtchannel dataset` (placeholder; filled in by the dataset work)."""


def add_dataset(sub) -> None:
    """Register the `dataset` subcommand."""
