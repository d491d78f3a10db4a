"""Calibrate a robot's model against measured logs: ``python calibrate.py --help``; the code is sysid/cli.py
and the guide docs/calibration.md."""

import signal
import sys

if __name__ == "__main__":
    signal.signal(signal.SIGINT, lambda *_: sys.exit(130))  # Ctrl-C while the libraries load: a quiet exit 130

from sysid.cli import main

if __name__ == "__main__":
    signal.signal(signal.SIGINT, signal.default_int_handler)  # from here a Ctrl-C is handled by main()
    sys.exit(main())
