"""The checker of :mod:`tests.test_architecture` on sources made up for it: it must
name every arrow that runs the wrong way (with its file and line), and let the right
ones through; a checker that found nothing would pass the real tree too."""

from __future__ import annotations

import pytest

from tests.test_architecture import violations

BAD_SOURCES = [
    pytest.param("localizer/x.py", "import pybullet\n", "'pybullet'", id="localizer-pybullet"),
    pytest.param(
        "localizer/x.py",
        "from mcap.reader import make_reader\n",
        "'mcap.reader",
        id="localizer-mcap",
    ),
    pytest.param("localizer/x.py", "import rerun as rr\n", "'rerun'", id="localizer-rerun"),
    pytest.param(
        "localizer/x.py",
        "def load():\n    from pipemap.replay import reader\n",
        "'pipemap.replay.reader'",
        id="localizer-replay-inside-function",
    ),
    pytest.param(
        "localizer/x.py",
        "from pipemap.cli import main\n",
        "'pipemap.cli.main'",
        id="localizer-cli",
    ),
    pytest.param("localizer/x.py", "import pipemap\n", "'pipemap'", id="localizer-pipemap"),
    pytest.param(
        "localizer/x.py",
        "from pipemap import __version__\n",
        "'pipemap.__version__'",
        id="localizer-pipemap-attr",
    ),
    pytest.param(
        "localizer/x.py", "from pathlib import Path\n", "'pathlib.Path'", id="localizer-pathlib"
    ),
    pytest.param("localizer/x.py", "import os.path\n", "'os.path'", id="localizer-os"),
    pytest.param("localizer/x.py", "import time\n", "'time'", id="localizer-time"),
    pytest.param(
        "localizer/x.py",
        "from datetime import datetime\n",
        "'datetime.datetime'",
        id="localizer-datetime",
    ),
    pytest.param(
        "localizer/x.py",
        "from logging import basicConfig\n",
        "'logging.basicConfig'",
        id="localizer-from-logging-basicconfig",
    ),
    pytest.param(
        "localizer/x.py",
        "import logging\nlogging.basicConfig(level=10)\n",
        "logging.basicConfig",
        id="localizer-logging-basicconfig",
    ),
    pytest.param(
        "localizer/x.py",
        "def f(p):\n    with open(p) as fh:\n        return fh\n",
        "open()",
        id="localizer-open",
    ),
    pytest.param(
        "localizer/x.py",
        "import cv2 as cv\nim = cv.imread('a.png')\n",
        "cv2.imread()",
        id="localizer-imread",
    ),
    pytest.param(
        "localizer/x.py",
        "import importlib\nm = importlib.import_module('pybullet')\n",
        "'pybullet'",
        id="localizer-dynamic-import",
    ),
    pytest.param(
        "localizer/sub/x.py",
        "from ....sim import world\n",
        "beyond top level",
        id="localizer-relative-escape",
    ),
    pytest.param(
        "localizer/x.py",
        "from ..sim import world\n",
        "'pipemap.sim.world'",
        id="localizer-relative-sibling-layer",
    ),
    pytest.param(
        "sim/x.py",
        "from pipemap.localizer import ImageSet\n",
        "'pipemap.localizer.ImageSet'",
        id="sim-localizer",
    ),
    pytest.param("sim/x.py", "import pipemap.recorder\n", "'pipemap.recorder'", id="sim-recorder"),
    pytest.param(
        "sim/x.py", "from mcap.writer import Writer\n", "'mcap.writer.Writer'", id="sim-mcap"
    ),
    pytest.param("sim/x.py", "from localizer import ImageSet\n", "live under", id="old-name"),
    pytest.param("pipemap/cli/x.py", "import sim.world\n", "live under", id="cli-old-name"),
    pytest.param(
        "recorder/x.py",
        "from pipemap.replay.score import score\n",
        "'pipemap.replay.score.score'",
        id="recorder-replay",
    ),
    pytest.param(
        "recorder/x.py",
        "from pipemap.imagesets import load_image_set\n",
        "'pipemap.imagesets.load_image_set'",
        id="recorder-imagesets",
    ),
    pytest.param(
        "replay/x.py", "import pipemap.sim.world\n", "'pipemap.sim.world'", id="replay-sim"
    ),
    pytest.param(
        "replay/x.py", "from pipemap.batch import run_batch\n", "'pipemap.batch", id="replay-batch"
    ),
    pytest.param(
        "recorder/x.py", "import pipemap.batch.spec\n", "'pipemap.batch.spec'", id="recorder-batch"
    ),
    pytest.param(
        "pipemap/batch/x.py",
        "from pipemap.cli.parser import build_parser\n",
        "'pipemap.cli.parser.build_parser'",
        id="batch-cli",
    ),
    pytest.param("pipemap/errors.py", "import numpy\n", "'numpy'", id="errors-numpy"),
    pytest.param("pipemap/errors.py", "from . import cli\n", "'pipemap.cli'", id="errors-cli"),
    pytest.param(
        "pipemap/__init__.py",
        "from pipemap.cli import main\n",
        "'pipemap.cli.main'",
        id="pipemap-init-cli",
    ),
]


@pytest.mark.parametrize(("relpath", "source", "named"), BAD_SOURCES)
def test_checker_catches_forbidden_import(relpath: str, source: str, named: str) -> None:
    problems = violations(source, relpath)
    assert len(problems) == 1, problems
    assert problems[0].startswith(f"{relpath}:"), problems[0]  # names the file and line
    assert named in problems[0], problems[0]  # names the import


GOOD_SOURCES = [
    pytest.param(
        "localizer/x.py",
        "from __future__ import annotations\nimport math\nimport numpy as np\n"
        "from scipy.signal import fftconvolve\nimport cv2\nimport networkx as nx\n"
        "from pipemap.errors import LocalizerError\nfrom pipemap import errors\n"
        "from ..errors import PipemapError\n"
        "import logging\nlog = logging.getLogger(__name__)\n"
        "from .similarity import SetMatch\nfrom pipemap.localizer.imageset import ImageSet\n"
        "small = cv2.resize(np.zeros((4, 4)), (2, 2))\n",
        id="localizer",
    ),
    pytest.param(
        "recorder/x.py",
        "import mcap\nfrom pipemap.sim import world\nfrom pipemap.localizer import Localizer\n"
        "from pipemap.errors import PipemapError\n",
        id="recorder",
    ),
    pytest.param(
        "replay/x.py",
        "from pipemap.recorder.topics import TOPICS\nimport pipemap.localizer\n"
        "def f():\n    import rerun\n",
        id="replay",
    ),
    pytest.param(
        "pipemap/cli/app.py",
        "from pipemap.replay import score\nfrom pipemap.recorder import Recorder\n"
        "import pipemap.sim\nfrom . import parser\n",
        id="cli",
    ),
    pytest.param(
        "pipemap/batch/x.py",
        "from pipemap import __version__\nfrom pipemap.recorder import record_run\n"
        "from pipemap.replay import score\nfrom pipemap.sim.network import build_network\n"
        "from pipemap.localizer import PAPER\nfrom pipemap.errors import InputError\n"
        "from . import spec\nimport ray\n",
        id="batch",
    ),
    pytest.param("pipemap/errors.py", "from __future__ import annotations\n", id="errors"),
]


@pytest.mark.parametrize(("relpath", "source"), GOOD_SOURCES)
def test_checker_allows_the_right_arrows(relpath: str, source: str) -> None:
    assert violations(source, relpath) == []
