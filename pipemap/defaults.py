"""The defaults of a run, written once: the camera, the sweep, the seed, the lighting.

The simulator's dataclasses (:class:`pipemap.sim.world.CameraSpec`, the explorer's and
the placement conditions' configurations), the recorder's
:class:`pipemap.recorder.RecordSettings`, a batch's keys and the command line's flags
all take their defaults from here, so that changing one changes them all; a test
checks that every parser's default settings equal the library's. The similarity
threshold is the localizer's own (:data:`pipemap.localizer.DEFAULT_THRESHOLD`).
Standard library only, and nothing of pipemap: every layer may import it, and
``pipemap --help`` stays instant.
"""

from __future__ import annotations

__all__ = [
    "IMAGES_PER_SWEEP",
    "IMAGE_FORMAT",
    "JPEG_QUALITY",
    "LAMP_STRENGTHS",
    "LIGHTING",
    "RESOLUTION_PX",
    "SEED",
]

#: The camera's square images, in pixels.
RESOLUTION_PX = 400
#: Images per junction sweep, 360/N degrees apart (the paper's six).
IMAGES_PER_SWEEP = 6
#: The seed of every random draw of a run.
SEED = 0
#: How the pipe is lit (``--lighting``), and the lamp's strength relative to full for
#: each: the robot's lamp alone, or every surface evenly as in the paper's simulation.
LAMP_STRENGTHS = {"lamp": 1.0, "even": 0.0}
LIGHTING = "lamp"
#: How a log stores the camera's images, and the JPEG quality (1..100) when ``jpeg``.
IMAGE_FORMAT = "png"
JPEG_QUALITY = 90
