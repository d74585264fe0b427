"""``python -m cli``: the ``pefsim`` command."""

import sys

from cli import main

sys.exit(main())
