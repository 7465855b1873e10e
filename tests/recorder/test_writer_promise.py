"""The log writer's promise holds at every moment: from the start of ``record`` the
named log exists and reads (a log of no messages until the writer's first chunk),
so a writer killed at once, before its first chunk, leaves what the message says.
"""

from __future__ import annotations

import io
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from pipemap.recorder import read_log
from pipemap.recorder.background import PLACEHOLDER_STATUS, _write_placeholder
from pipemap.recorder.topics import METADATA_RESULT, METADATA_RUN
from pipemap.recorder.writer import LogWriter

RUN = {"pipemap_version": "test", "network": "paper", "seed": "3"}


def _writer_of(parent: int) -> int | None:
    """The pid of ``parent``'s log writer process, once it runs."""
    children = Path(f"/proc/{parent}/task/{parent}/children")
    for pid in children.read_text().split() if children.exists() else ():
        try:
            command = Path(f"/proc/{pid}/cmdline").read_bytes()
        except OSError:
            continue
        if b"pipemap.recorder.writer_process" in command:
            return int(pid)
    return None


def test_the_placeholder_starts_with_the_bytes_the_writer_writes_first(tmp_path: Path) -> None:
    target = tmp_path / "run.mcap"
    _write_placeholder(target, "xb", RUN)
    contents = read_log(target)
    assert contents.metadata[METADATA_RESULT]["status"] == PLACEHOLDER_STATUS
    assert sum(contents.counts.values()) == 0
    first = io.BytesIO()
    writer = LogWriter(first, RUN)
    writer.flush()  # nothing in a chunk yet: only what the writer writes at once
    head = first.getvalue()
    assert len(head) > 8 and target.read_bytes().startswith(head)
    assert contents.metadata[METADATA_RUN]["network"] == "paper"


def test_a_writer_killed_before_its_first_chunk_leaves_a_log_that_reads(tmp_path: Path) -> None:
    target = tmp_path / "run.mcap"
    process = subprocess.Popen(
        [sys.executable, "-m", "pipemap", "record", "--network", "paper", "--resolution", "32"]
        + ["-o", str(target)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 120
    writer = None
    while writer is None and time.monotonic() < deadline and process.poll() is None:
        writer = _writer_of(process.pid)
    assert writer is not None, process.communicate()
    # The log exists and reads from the moment the writer runs, before it wrote a byte.
    assert read_log(target).metadata[METADATA_RUN]["network"] == "paper"
    os.kill(writer, signal.SIGKILL)
    _, err = process.communicate(timeout=300)
    assert process.returncode == 3, err
    assert err.splitlines()[-1].startswith("pipemap: error: the log writer process was killed")
    assert "Traceback" not in err
    contents = read_log(target)  # what the message promises: it reads
    assert contents.metadata[METADATA_RUN]["network"] == "paper"
    info = subprocess.run(
        [sys.executable, "-m", "pipemap", "info", str(target)], capture_output=True, text=True
    )
    assert info.returncode in (0, 1), info.stderr
