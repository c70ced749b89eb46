"""PPO from scratch (SB3) on an ``IAS-*`` task, saved as ``FILE.zip``.

    python train/ppo.py --env IAS-PenSlide-v0 --steps 100000 --out out/ppo_slide.zip

The training itself is in ``train/from_scratch.py`` (shared with train/sac.py).
"""

from __future__ import annotations

import sys

from from_scratch import main

if __name__ == "__main__":
    sys.exit(main("ppo", __doc__.split("\n\n")[0]))
