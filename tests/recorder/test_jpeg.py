"""``pipemap record --image-format jpeg [--jpeg-quality Q]``: a log whose images are
JPEG, which the replay decodes as it does PNG."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pipemap import api  # noqa: I001
from pipemap.cli import main
from pipemap.errors import InputError
from pipemap.recorder import RecordSettings, Topic, read_log
from pipemap.recorder.messages import ImageEncoding, decode_image, image_message
from pipemap.recorder.schemas import CompressedImage
from tests.logs import record


def _quantization(jpeg: bytes) -> bytes:
    """The JPEG's quantization tables (its DQT segments): what the quality sets."""
    tables, k = b"", 2
    while k + 4 <= len(jpeg) and jpeg[k] == 0xFF:
        marker, length = jpeg[k + 1], int.from_bytes(jpeg[k + 2 : k + 4], "big")
        if marker == 0xDB:
            tables += jpeg[k + 4 : k + 2 + length]
        if marker == 0xDA:  # the scan: no more tables
            break
        k += 2 + length
    return tables


def _rgb(seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    ramp = np.linspace(0, 255, 48, dtype=np.float32)[None, :, None]
    noise = rng.normal(0, 8, (40, 48, 3)).astype(np.float32)
    return np.clip(ramp + noise, 0, 255).astype(np.uint8)


def test_a_jpeg_image_decodes_close_to_what_was_encoded() -> None:
    rgb = _rgb()
    message = image_message(5, rgb, ImageEncoding("jpeg", 95))
    assert message.format == "jpeg"
    back = decode_image(message.data, "jpeg")
    assert back is not None and back.shape == rgb.shape
    # Within the noise of the test image (chroma is subsampled): the picture is kept.
    assert np.abs(back.astype(int) - rgb.astype(int)).mean() < 8.0
    assert decode_image(message.data[:-10], "jpeg") is None  # cut short: no end marker
    assert decode_image(message.data, "gif") is None


def test_the_quality_sets_the_tables_and_the_size() -> None:
    rgb = _rgb()
    high, low = ImageEncoding("jpeg", 95).encode(rgb), ImageEncoding("jpeg", 20).encode(rgb)
    assert len(low) < len(high)
    assert _quantization(low) != _quantization(high)
    with pytest.raises(ValueError, match="not in 1..100"):
        ImageEncoding("jpeg", 0)
    with pytest.raises(InputError, match="image format 'gif'"):
        RecordSettings(network="paper", image_format="gif")


def test_a_png_run_names_no_image_format() -> None:
    """A PNG log's metadata (and so its bytes) stays as it always was."""
    assert ImageEncoding().metadata() == {}
    assert ImageEncoding.of_run({}) == ImageEncoding()
    assert ImageEncoding.of_run({"image_format": "jpeg", "jpeg_quality": "30"}) == ImageEncoding(
        "jpeg", 30
    )


def test_jpeg_quality_needs_the_jpeg_format(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    status = main(
        ["record", "--network", "paper", "--jpeg-quality", "50", "-o", str(tmp_path / "r.mcap")]
    )
    assert status == 2 and "needs --image-format jpeg" in capsys.readouterr().err
    assert not (tmp_path / "r.mcap").exists()
    with pytest.raises(SystemExit) as exited:
        main(
            [
                "record",
                "--network",
                "paper",
                "--image-format",
                "jpeg",
                "--jpeg-quality",
                "0",
                "-o",
                str(tmp_path / "r.mcap"),
            ]
        )
    assert exited.value.code == 2 and "JPEG quality must be 1..100" in capsys.readouterr().err


def test_a_jpeg_run_records_jpeg_at_its_quality_and_replays(tmp_path: Path) -> None:
    # tree:3 (5 sweeps at seed 3): a run to encode and replay, in a cheap world.
    done = record(
        tmp_path / "run.mcap",
        "--network",
        "tree:3",
        "--image-format",
        "jpeg",
        "--jpeg-quality",
        "30",
    )
    assert done.returncode == 0, done.stderr
    log = read_log(tmp_path / "run.mcap")
    run = log.metadata["pipemap.run"]
    assert (run["image_format"], run["jpeg_quality"]) == ("jpeg", "30")
    images = [CompressedImage.FromString(m.data) for m in log.messages if m.topic == Topic.IMAGE]
    assert images and {i.format for i in images} == {"jpeg"}
    # Encoded at quality 30: the quantization tables of OpenCV's encoder at 30.
    expected = _quantization(ImageEncoding("jpeg", 30).encode(_rgb()))
    assert {_quantization(i.data) for i in images} == {expected}
    replayed = api.replay(tmp_path / "run.mcap")
    assert len(replayed.document()["visits"]) == 5
    score = api.score(tmp_path / "run.mcap")
    assert score.visits and score.coverage is not None
    assert json.loads(api.dumps_document(replayed.document()))["nodes"]
