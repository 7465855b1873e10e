"""Files that hold more than one run: several logs merged into one by another program
(each brings its ``pipemap.run`` record), or log files joined end to end (another MCAP
file after the log's closing magic, which the walk does not read). What is found is
named for ``info``; a replay, a score and a view refuse such a file, since a map or a
score is of one run and the file does not say which one is meant."""

from __future__ import annotations

from pipemap.recorder.mcapfile import Scan
from pipemap.recorder.topics import METADATA_RUN

__all__ = ["indexed_runs", "several_runs"]

#: How a merge of several runs is told to be parted.
_ONE_RUN = "; pipemap replays one run a log: keep each run in a file of its own"


def indexed_runs(names: list[str]) -> str:
    """What the summary's metadata index ``names`` tell of several runs ("" for one)."""
    runs = names.count(METADATA_RUN)
    if runs < 2:
        return ""
    return (
        f"holds {runs} runs ({runs} {METADATA_RUN} records, merged into one file by another "
        f"program){_ONE_RUN}"
    )


def several_runs(
    metadata: dict[str, dict[str, str]], found: Scan, size: int
) -> tuple[list[tuple[int, str]], str]:
    """The runs after the first in a walked file of ``size`` bytes whose metadata (the
    first record of each name) is ``metadata``: where each is and what it is, and what
    the file holds and how to part it ("" for one run)."""
    damage: list[tuple[int, str]] = []
    several = ""
    runs = [(at, values) for name, at, values in found.repeated_metadata if name == METADATA_RUN]
    if runs:
        first = metadata.get(METADATA_RUN, {})
        settings = "; ".join(_settings(values) for values in [first] + [v for _, v in runs])
        count = len(runs) + 1
        for at, values in runs:
            damage.append(
                (
                    at,
                    f"another {METADATA_RUN} record ({_settings(values)}): the file holds "
                    f"{count} runs, merged by another program",
                )
            )
        several = (
            f"holds {count} runs ({count} {METADATA_RUN} records: {settings}), merged into one "
            f"file by another program{_ONE_RUN}"
        )
    if found.joined_at:
        at = found.joined_at
        damage.append(
            (
                at,
                f"another MCAP file of {size - at} bytes begins after the log's closing magic "
                "(two files joined end to end): it is not read",
            )
        )
        several = (
            f"holds two MCAP files joined end to end (the second begins at byte {at}); pipemap "
            f"replays one run a log: part them with head -c {at} and tail -c +{at + 1}"
        )
    return damage, several


def _settings(run: dict[str, str]) -> str:
    """A run's settings in a few words: network, seed, condition."""
    return ", ".join(f"{key} {run.get(key, '?')}" for key in ("network", "seed", "condition"))
