"""Entry point of the log writer process (see :mod:`recorder.background`).

``python -m recorder.writer_process RECORDS_FD REPLIES_FD PATH MODE``: reads
pickled record batches from one pipe, writes the log at ``PATH``, answers on the
other. Not for use by hand.
"""

from __future__ import annotations

import contextlib
import os
import sys

from pipemap.recorder.background import writer_main

if __name__ == "__main__":
    records_fd, replies_fd, path, mode = sys.argv[1:5]
    records, replies = os.fdopen(int(records_fd), "rb"), os.fdopen(int(replies_fd), "wb")
    try:
        code = writer_main(records, replies, path, mode)
    finally:
        for stream in (records, replies):
            # A recording process that was killed left a broken pipe: nobody to tell.
            with contextlib.suppress(OSError):
                stream.close()
    sys.exit(code)
