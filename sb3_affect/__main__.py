"""``python -m sb3_affect``: the same entry point as the ``sb3-affect`` console script."""

import sys

from sb3_affect.study.cli import main

sys.exit(main())
