"""pipemap: topological localization and mapping of robots in buried pipe networks.

This package is the application shell: the error root shared by every layer and
the ``pipemap`` command line. The layers themselves are the top-level packages
``sim``, ``recorder``, ``replay`` and ``localizer``.
"""

from __future__ import annotations

__version__ = "0.1.0"

__all__ = ["__version__"]
