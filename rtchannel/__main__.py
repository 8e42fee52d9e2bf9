"""`python -m rtchannel` = the `rtchannel` command."""
import sys

from rtchannel.cli import main

sys.exit(main())
