"""Thin launcher: ``python experiments/launch.py run experiments/paper.yaml --out runs/paper`` = ``sb3-affect ...``."""

import sys

from sb3_affect.study.cli import main

if __name__ == "__main__":
    sys.exit(main())
