"""Compare policies (scripted gaits and trained models) on the same episode seeds: ``python evaluate.py --help``;
the code is agents/compare.py and the guide docs/training.md."""

import os
import signal
import sys

if __name__ == "__main__":
    signal.signal(signal.SIGINT, lambda *_: sys.exit(130))  # Ctrl-C while the libraries load: a quiet exit 130

os.environ.setdefault("MUJOCO_GL", "egl")  # headless rendering (--video), unless the user chose a backend

from agents.compare import main

if __name__ == "__main__":
    signal.signal(signal.SIGINT, signal.default_int_handler)  # from here a Ctrl-C is handled by main()
    sys.exit(main())
