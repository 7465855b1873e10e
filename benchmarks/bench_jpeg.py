"""What storing the camera's images as JPEG does to a replay's decisions.

    python benchmarks/bench_jpeg.py [--qualities 95,90,75,50,25,10] [LOG.mcap ...]

Each log (default: the committed recordings, 96 px, PNG) is written again with its
images as JPEG at each quality, then scored as ``pipemap score`` does. A log recorded
with ``pipemap record --image-format jpeg --jpeg-quality Q`` holds these very bytes:
the robot, its online localizer and its path see the camera's own pixels whatever the
log stores, and the recorder encodes each image with the same OpenCV call. Prints one
row per log and quality: image bytes against PNG, the map, the decisions by outcome,
and how many visits' outcome (right or wrong, known or new) differs from the PNG
log's replay.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from pipemap import api
from pipemap.recorder import Topic, read_log
from pipemap.recorder.messages import ImageEncoding, decode_png
from pipemap.recorder.schemas import CompressedImage
from pipemap.recorder.writer import LogWriter

ROOT = Path(__file__).resolve().parents[1]
LOGS = ("paper_autonomous.mcap", "paper_active.mcap", "random8_loops.mcap")


def transcode(source: Path, target: Path, encoding: ImageEncoding) -> int:
    """``source`` written again to ``target`` with its images in ``encoding``;
    returns the images' bytes."""
    contents = read_log(source)
    run = dict(contents.metadata["pipemap.run"])
    run.pop("format_version", None)
    run.update(encoding.metadata())
    total = 0
    with target.open("wb") as output, LogWriter(output, run) as log:
        for m in contents.messages:
            data = m.data
            if m.topic == Topic.IMAGE:
                image = CompressedImage.FromString(data)
                rgb = decode_png(image.data)
                assert rgb is not None, f"{source}: an image is not a readable PNG"
                image.data = encoding.encode(rgb)
                image.format = encoding.image_format
                data = image.SerializeToString()
                total += len(image.data)
            log.write_serialized(m.topic, m.log_time_ns, data)
    return total


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "logs", nargs="*", type=Path, default=[ROOT / "recordings" / n for n in LOGS]
    )
    parser.add_argument("--qualities", default="95,90,75,50,25,10")
    args = parser.parse_args()
    qualities = [int(q) for q in args.qualities.split(",")]
    print(
        "| log | images | bytes vs PNG | map | known ok | new ok | false merge | false new "
        "| outcome differs |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for log in args.logs:
            png = Path(tmp) / "png.mcap"
            png_bytes = transcode(log, png, ImageEncoding())
            reference = api.score(png)
            outcomes = [v.outcome for v in reference.visits]
            rows = [("png", png, png_bytes)]
            for q in qualities:
                target = Path(tmp) / f"q{q}.mcap"
                rows.append((f"jpeg {q}", target, transcode(log, target, ImageEncoding("jpeg", q))))
            for name, path, size in rows:
                report = reference if path == png else api.score(path)
                c = report.counts()
                other = sum(
                    1 for v, o in zip(report.visits, outcomes, strict=False) if v.outcome != o
                )
                print(
                    f"| {log.name} | {name} | {size / png_bytes:.2f} | {report.map_status} | "
                    f"{c['correct_known']} | {c['correct_new']} | {c['false_merge']} | "
                    f"{c['false_new']} | {other} |",
                    flush=True,
                )


if __name__ == "__main__":
    main()
