"""``python -m pipemap``: the same as the ``pipemap`` command."""

from __future__ import annotations

import sys

from pipemap.cli import main

sys.exit(main())
