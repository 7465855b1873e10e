"""The ``pipemap`` command line: the only layer that parses arguments, configures
logging, prints and exits. Everything else it calls is library code."""

from __future__ import annotations

from pipemap.cli.app import main

__all__ = ["main"]
