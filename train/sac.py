"""SAC from scratch (SB3) on an ``IAS-*`` task, saved as ``FILE.zip``.

    python train/sac.py --env IAS-PenSlide-v0 --steps 100000 --out out/sac_slide.zip

The training itself is in ``train/from_scratch.py`` (shared with train/ppo.py).
"""

from __future__ import annotations

import sys

from from_scratch import main

if __name__ == "__main__":
    sys.exit(main("sac", __doc__.split("\n\n")[0]))
