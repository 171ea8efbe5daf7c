"""``python -m ltd_brake_ros.cli``: same as ``ltd-brake``."""
import sys

from .main import main

sys.exit(main())
