"""``python -m agents.cli``: the ``vrloco`` command line."""

import sys

from agents.cli import main

sys.exit(main())
