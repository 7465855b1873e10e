"""Every MCAP reader reads pipemap's logs: the TypeScript reference (``@mcap/core``,
what Foxglove is built on) by index and as a stream, and the ``mcap`` Python library
by index; each finds as many messages per topic as ``pipemap info`` counts.

``@mcap/core`` is installed with npm into a folder of the test session's own, once
per session. The test is skipped only where npm itself is missing.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest
from mcap.reader import make_reader

RECORDINGS = Path(__file__).resolve().parents[2] / "recordings"
STORED = sorted(RECORDINGS.glob("*.mcap"))
#: Exact versions, so that a new release cannot change what the test means.
NPM_PACKAGES = ("@mcap/core@2.2.2", "@foxglove/wasm-zstd@1.0.1")
SCRIPT = Path(__file__).parent / "js" / "mcap_counts.js"


@pytest.fixture(scope="session")
def mcap_core(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder with ``@mcap/core`` installed and the counting script beside it."""
    npm = shutil.which("npm")
    if npm is None or shutil.which("node") is None:
        pytest.skip("npm and node are not installed: cannot install @mcap/core to read logs")
    folder = tmp_path_factory.mktemp("mcap_core")
    (folder / "package.json").write_text('{"name": "pipemap-mcap-check", "private": true}\n')
    done = subprocess.run(
        [npm, "install", "--no-audit", "--no-fund", "--no-save", *NPM_PACKAGES],
        cwd=folder,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, f"npm install {' '.join(NPM_PACKAGES)} failed:\n{done.stderr}"
    shutil.copy(SCRIPT, folder / SCRIPT.name)
    return folder / SCRIPT.name


def typescript_counts(script: Path, log: Path) -> dict[str, dict[str, int]]:
    """Messages per topic as ``@mcap/core``'s indexed and streaming readers find them."""
    done = subprocess.run(
        ["node", str(script), str(log)], capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, f"@mcap/core cannot read {log}:\n{done.stderr}"
    found: dict[str, dict[str, int]] = json.loads(done.stdout)[str(log)]
    return found


def info_counts(log: Path) -> dict[str, int]:
    done = subprocess.run(
        [sys.executable, "-m", "pipemap", "info", "--json", str(log)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    return {c["topic"]: c["count"] for c in json.loads(done.stdout)["channels"]}


def python_indexed_counts(log: Path) -> dict[str, int]:
    with log.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None and summary.chunk_indexes, "no chunk indexes"
        counts = Counter({channel.topic: 0 for channel in summary.channels.values()})
        for _, channel, _ in reader.iter_messages():
            counts[channel.topic] += 1
    return dict(counts)


def check_log(script: Path, log: Path) -> None:
    expected = info_counts(log)
    assert sum(expected.values()) > 0
    found = typescript_counts(script, log)
    assert found["indexed"] == expected, "@mcap/core McapIndexedReader"
    assert found["stream"] == expected, "@mcap/core McapStreamReader"
    assert found["done"], "the stream reader did not reach the end of the file"
    assert found["metadata"] == ["pipemap.run", "pipemap.result"]
    assert python_indexed_counts(log) == expected, "mcap (Python), by index"


def test_a_fresh_log_reads_in_every_mcap_reader(mcap_core: Path, recorded_run: Path) -> None:
    check_log(mcap_core, recorded_run)


@pytest.mark.parametrize("log", STORED, ids=[p.stem for p in STORED])
def test_every_stored_log_reads_in_every_mcap_reader(mcap_core: Path, log: Path) -> None:
    check_log(mcap_core, log)
