"""The activity names the motion generators and importers accept: `processing.labels.ACTIVITIES` (their
order is the class-label order), re-exported without dependencies for the CLI's argument parser."""

from processing.labels import ACTIVITIES

__all__ = ["ACTIVITIES"]
