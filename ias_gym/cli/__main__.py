"""``python -m ias_gym.cli``: the ``ias-gym`` command (the glove bench starts its emulator so)."""

import sys

from ias_gym.cli import main

sys.exit(main())
