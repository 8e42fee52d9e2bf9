"""`python -m rtchannel` = the `rtchannel` command."""
import sys

from rtchannel.cli import run

sys.exit(run())
