"""The one error root of pipemap.

Library code raises a subclass of :class:`PipemapError` whose message names the
offending value; only the command line catches it, prints it as one line and
exits with status 2, or 3 for a :class:`WriteError` (an output that could not be
written whole). Any other exception is a bug and keeps its traceback.
"""

from __future__ import annotations

__all__ = [
    "InputError",
    "Interrupted",
    "LocalizerError",
    "LogFormatError",
    "PipemapError",
    "SimError",
    "ViewerError",
    "WriteError",
]


class PipemapError(Exception):
    """Base of every error that is the user's input, not a bug."""


class InputError(PipemapError):
    """A file, folder, flag or value given by the user is missing or malformed."""


class LocalizerError(PipemapError):
    """The localizer was given data it cannot work with (sizes, counts, settings)."""


class SimError(PipemapError):
    """A simulation was asked for something impossible: a malformed network, a bad setting."""


class LogFormatError(PipemapError):
    """A log file is missing, is not an MCAP file, or is not a pipemap log."""


class ViewerError(PipemapError):
    """The rerun viewer cannot be started or reached (no display, no connection)."""


class WriteError(PipemapError):
    """Writing an output failed part-way: a full disk, a killed log writer. What was
    written before stays readable; the command line exits with status 3."""


class Interrupted(KeyboardInterrupt):
    """A stop signal (SIGINT, SIGTERM, SIGHUP) raised where Ctrl-C would be, so that
    every command cleans up the same way; ``signum`` says which one arrived, and the
    command line exits with 128 + ``signum``."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = int(signum)
