"""`rtchannel train / evaluate / crossval` (placeholder; filled in by the classifier work)."""


def add_classifier_commands(sub) -> None:
    """Register the `train`, `evaluate` and `crossval` subcommands."""
