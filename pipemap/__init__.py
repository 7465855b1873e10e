"""pipemap: topological localization and mapping of robots in buried pipe networks.

Everything installs under this one name: the layers ``pipemap.sim`` (the world and
the robot), ``pipemap.recorder`` (a run to an MCAP log), ``pipemap.replay`` (a log
back through the localizer, scored) and ``pipemap.localizer`` (the algorithm, pure),
the command line ``pipemap.cli``, and ``pipemap.errors``, the error root every layer
shares. Importing this package loads none of them.
"""

from __future__ import annotations

#: The one place the version is written (pyproject.toml reads it from here).
__version__ = "0.2.0"

__all__ = ["__version__"]
