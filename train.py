"""Train a Stable-Baselines3 agent on a skitter env: ``python train.py --help``; the code is agents/training.py and
the guide docs/training.md."""

import signal
import sys

if __name__ == "__main__":
    signal.signal(signal.SIGINT, lambda *_: sys.exit(130))  # Ctrl-C while the libraries load: a quiet exit 130

from agents.training import main

if __name__ == "__main__":
    signal.signal(signal.SIGINT, signal.default_int_handler)  # from here a Ctrl-C is handled by main()
    sys.exit(main())
