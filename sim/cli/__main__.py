"""``python -m sim.cli``: the ``pefsim`` command."""

import sys

from sim.cli import main

sys.exit(main())
