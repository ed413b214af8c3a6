"""``python -m findme.cli``: the ``findme`` command (what ``findme up`` starts its children with)."""

import sys

from . import main

sys.exit(main())
