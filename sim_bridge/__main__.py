"""``python -m sim_bridge`` = ``gcs-sim``."""

import sys

from sim_bridge.cli import main

sys.exit(main())
