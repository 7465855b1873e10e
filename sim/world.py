"""The simulated world: a pipe network in a headless PyBullet client.

Each half-pipe and each junction chamber is a static body with a visual mesh, a
texture from the seeded aged-pipe family and a concave collision mesh (for range
rays). Both halves of a pipe share one texture, so a pipe looks continuous and
every junction looks like itself and no other.

The world is streamed (``stream=True``, the default): a piece (a pipe or a node's
chamber, :mod:`sim.world_pieces`) is built when an image or a range ray first needs
it, so building a world takes no time and its memory follows what the robot's
cameras and rangers have reached, not the network. Each piece draws its texture from
its own seed, so the images and ranges are those of the world built whole
(``stream=False``) to the bit. Pieces are never released: PyBullet keeps memory of
removed bodies and of closed clients (``benchmarks/bench_world_memory.py``).

Rendering uses TinyRenderer (no GPU, no window) for the albedo and depth of each
pixel, then lights the scene. A real pipe robot carries a lamp at the camera;
TinyRenderer only knows directional light, so the lamp is applied afterwards from
the depth buffer (inverse-square falloff along each pixel's ray times the cosine
of the angle between ray and surface), mixed with uniform light by
``CameraSpec.lamp_strength``. The default is the lamp alone, as in a buried pipe;
see that field.

PyBullet pitfalls seen in a probe and avoided here: removing bodies leaks mesh
memory (no body is ever removed); a camera exactly on a
ring of mesh vertices rendered 100x slower (callers nudge the eye by 0.1 mm).

TinyRenderer draws every body for every image, so before each image the world
hides (alpha 0: TinyRenderer skips the body) every body no line of sight from the
eye can reach (:mod:`sim.visibility`); the image stays the same to the bit (but for
pixels that look out of the network through a crack between two meshes: see
docs/culling.md), and its cost follows what is near the camera, not the network. Collision,
and so the range rays, keeps every body.
"""

from __future__ import annotations

import contextlib
import functools
import math
import os
import shutil
import sys
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from pipemap.defaults import LAMP_STRENGTHS, LIGHTING, RESOLUTION_PX
from pipemap.errors import SimError, WriteError
from pipemap.sim.lookalike import LookAlike
from pipemap.sim.network import Network
from pipemap.sim.obstacles import Obstacle
from pipemap.sim.visibility import ALL, Arc, PortalGraph, frustum_arc, visible_parts
from pipemap.sim.world_pieces import Pieces

__all__ = ["CameraSpec", "World", "body_rotation"]


def _import_pybullet_quietly() -> Any:
    """Import pybullet without its build-time banner, which its C code writes to fd 2:
    a one-line error from the command line must stay one line."""
    sys.stderr.flush()
    saved = os.dup(2)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 2)
        import pybullet as module
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)
    return module


pybullet = _import_pybullet_quietly()

#: Distance at which the lamp lights a surface facing it at full albedo: the pipe
#: wall beside the camera, so nothing nearby saturates and the far pipe fades out.
LAMP_REFERENCE_M = 0.12
NEAR_M = 0.005
#: The seed stream of the deposits' textures (with the world's seed).
_DEPOSIT_STREAM = 22
FAR_M = 30.0


@dataclass(frozen=True)
class CameraSpec:
    """A pinhole camera: square images, horizontal field of view."""

    resolution_px: int = RESOLUTION_PX
    fov_rad: float = math.radians(80.0)
    #: Share of the light that comes from a lamp at the camera (inverse-square
    #: falloff from ``LAMP_REFERENCE_M``, incidence shading); the rest is uniform.
    #: Default 1.0: a buried pipe has no light but the robot's own, so nothing is lit
    #: beyond the lamp's reach. 0.0 is the paper's evenly lit simulation
    #: (``--lighting even``). Under the lamp the paper's whole-image NCC cannot tell
    #: junctions apart unaided; the localizer normalises illumination (docs/lighting.md).
    lamp_strength: float = LAMP_STRENGTHS[LIGHTING]

    def __post_init__(self) -> None:
        if not 16 <= self.resolution_px <= 4096:
            raise SimError(f"camera resolution must be 16..4096 px, got {self.resolution_px}")
        if not 0.0 < self.fov_rad < math.pi:
            raise SimError(f"camera field of view must be in (0, pi), got {self.fov_rad}")
        if not 0.0 <= self.lamp_strength <= 1.0:
            raise SimError(f"lamp strength must be in [0, 1], got {self.lamp_strength}")


#: Start of the name of each world's folder of texture files (in the temporary folder).
_TEXTURE_PREFIX = "pipemap-world-"


def _texture_folder() -> tempfile.TemporaryDirectory[str]:
    """A new folder for a world's texture files, named after this process; the folders
    of processes that no longer run (killed while building a world) are removed first."""
    root = Path(tempfile.gettempdir())
    with contextlib.suppress(OSError):
        for stale in root.glob(f"{_TEXTURE_PREFIX}*-*"):
            pid = stale.name[len(_TEXTURE_PREFIX) :].split("-", 1)[0]
            if pid.isdigit() and not _running(int(pid)):
                shutil.rmtree(stale, ignore_errors=True)
    try:
        return tempfile.TemporaryDirectory(prefix=f"{_TEXTURE_PREFIX}{os.getpid()}-")
    except OSError as exc:
        raise WriteError(
            f"{root}: cannot make a folder for the world's texture files ({exc.strerror or exc})"
        ) from None


def _running(pid: int) -> bool:
    """Whether a process ``pid`` exists (another user's counts as existing)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True
    return True


class World:
    """A pipe network in its own PyBullet client. Use as a context manager."""

    def __init__(
        self,
        network: Network,
        seed: int,
        texture_px: int = 512,
        cull: bool = True,
        obstacles: tuple[Obstacle, ...] = (),
        looks: LookAlike | None = None,
        on_build: Callable[[int, int], None] | None = None,
        stream: bool = True,
    ) -> None:
        self.network = network
        #: The junctions that share a look (:mod:`sim.lookalike`); none by default.
        self.looks = looks if looks is not None else LookAlike(0.0)
        #: Called with (pieces built, pieces in all) as the world is built, a piece
        #: being a pipe or a node: a large network takes minutes.
        self._on_build = on_build
        #: Deposits on the pipe floors (:mod:`sim.obstacles`): bodies the camera and
        #: the rays see, and footprints the robot cannot drive into.
        self.obstacles = tuple(obstacles)
        self.radius_m = network.diameter_m / 2.0
        #: Hide, for each image, the bodies no line of sight can reach (same image).
        self.cull = cull
        self._client = pybullet.connect(pybullet.DIRECT)
        self._tmp = _texture_folder()
        #: Build each piece when an image or a range ray first needs it (the default),
        #: or every piece now (``stream=False``); the images are the same.
        self.stream = stream
        self._pieces = Pieces(
            pybullet, self._client, network, self.looks, seed, texture_px, Path(self._tmp.name)
        )
        self._node_bodies = self._pieces.node_bodies
        self._pipe_bodies = self._pieces.pipe_bodies
        self._hidden: set[int] = set()
        self._portals = PortalGraph(network)
        #: Bodies drawn by the last image (all of them when nothing was culled).
        self.drawn_bodies = 0
        try:
            if not stream:
                self._pieces.everything(self._on_build)
            if self.obstacles:
                self._build_obstacles(np.random.default_rng([seed, _DEPOSIT_STREAM]))
        except BaseException:
            self.close()
            raise

    @property
    def triangle_count(self) -> int:
        """Triangles of the pieces built so far."""
        return self._pieces.triangle_count

    @property
    def pieces_built(self) -> tuple[int, int]:
        """(pieces built so far, pieces in all), a piece being a pipe or a node."""
        return self._pieces.built, self._pieces.pieces

    def __enter__(self) -> World:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Disconnect the client and remove the texture files."""
        if self._client is not None and self._client >= 0:
            pybullet.disconnect(physicsClientId=self._client)
            self._client = -1
        self._tmp.cleanup()

    # -- building ---------------------------------------------------------------------

    def _build_obstacles(self, rng: np.random.Generator) -> None:
        """A textured box per deposit, drawn and culled with its pipe."""
        kwargs: dict[str, Any] = {"physicsClientId": self._client}
        for k, o in enumerate(self.obstacles):
            # Sediment: brown, mottled, darker where wet.
            shade = rng.uniform(0.55, 1.0, (32, 32, 1)).astype(np.float32)
            texture = np.clip(shade * np.array([150.0, 110.0, 70.0]), 0, 255).astype(np.uint8)
            tid = self._pieces._texture(f"deposit-{k}", cv2.resize(texture, (64, 64)))
            half = [o.length_m / 2.0, o.width_m / 2.0, o.height_m / 2.0]
            visual = pybullet.createVisualShape(pybullet.GEOM_BOX, halfExtents=half, **kwargs)
            collision = pybullet.createCollisionShape(pybullet.GEOM_BOX, halfExtents=half, **kwargs)
            body = pybullet.createMultiBody(
                baseMass=0.0,
                baseCollisionShapeIndex=collision,
                baseVisualShapeIndex=visual,
                basePosition=[o.centre_xy_m[0], o.centre_xy_m[1], o.height_m / 2.0],
                baseOrientation=pybullet.getQuaternionFromEuler([0.0, 0.0, o.heading_rad]),
                **kwargs,
            )
            pybullet.changeVisualShape(body, -1, textureUniqueId=tid, **kwargs)
            self._pipe_bodies.setdefault((o.a, o.b), []).append(int(body))
            self._node_bodies[o.a].append(int(body))
            self._node_bodies[o.b].append(int(body))

    # -- sensing ----------------------------------------------------------------------

    def _cull(self, eye_xyz_m: tuple[float, float, float], view: tuple[float, float]) -> None:
        """Hide the bodies no line of sight from the eye can reach, show the others."""
        parts = None
        if self.cull:
            parts = visible_parts(self._portals, (eye_xyz_m[0], eye_xyz_m[1]), view)
        if parts is None:
            self._pieces.everything()
        else:
            self._pieces.parts(*parts)
        everything = {b for bodies in self._pipe_bodies.values() for b in bodies}
        everything.update(b for bodies in self._node_bodies.values() for b in bodies)
        if not self.cull and not self._hidden:
            self.drawn_bodies = len(everything)
            return
        if parts is None:
            shown = everything
        else:
            nodes, pipes = parts
            shown = {b for n in nodes for b in self._node_bodies[n]}
            shown.update(b for p in pipes for b in self._pipe_bodies[p])
        hidden = everything - shown
        kwargs: dict[str, Any] = {"physicsClientId": self._client}
        for body in hidden - self._hidden:
            pybullet.changeVisualShape(body, -1, rgbaColor=[1.0, 1.0, 1.0, 0.0], **kwargs)
        for body in self._hidden - hidden:
            pybullet.changeVisualShape(body, -1, rgbaColor=[1.0, 1.0, 1.0, 1.0], **kwargs)
        self._hidden = hidden
        self.drawn_bodies = len(shown)

    def render(
        self,
        eye_xyz_m: tuple[float, float, float],
        yaw_rad: float,
        camera: CameraSpec,
        pitch_rad: float = 0.0,
    ) -> np.ndarray:
        """What the camera sees, lit by a lamp at the camera: RGB uint8 (H, W, 3)."""
        forward = np.array(
            [
                math.cos(pitch_rad) * math.cos(yaw_rad),
                math.cos(pitch_rad) * math.sin(yaw_rad),
                math.sin(pitch_rad),
            ]
        )
        arc = frustum_arc(yaw_rad, pitch_rad, camera.fov_rad)
        return self._render(eye_xyz_m, forward, np.array([0.0, 0.0, 1.0]), camera, arc)

    def render_tilted(
        self,
        eye_xyz_m: tuple[float, float, float],
        heading_rad: float,
        camera_angle_rad: float,
        roll_rad: float,
        pitch_rad: float,
        camera: CameraSpec,
    ) -> np.ndarray:
        """What the camera sees on a robot standing off level: the camera turns by
        ``camera_angle_rad`` (counter-clockwise) about the axis of a body that is
        rolled, pitched (nose down positive) and headed as given."""
        body = body_rotation(heading_rad, roll_rad, pitch_rad)
        look = np.array([math.cos(camera_angle_rad), math.sin(camera_angle_rad), 0.0])
        # frustum_arc assumes an unrolled camera: a rolled one may see any way round.
        return self._render(eye_xyz_m, body @ look, body[:, 2], camera, ALL)

    def _render(
        self,
        eye_xyz_m: tuple[float, float, float],
        forward: np.ndarray,
        up: np.ndarray,
        camera: CameraSpec,
        arc: Arc,
    ) -> np.ndarray:
        """Draw, after hiding what no line of sight within ``arc`` reaches."""
        res = camera.resolution_px
        eye = np.asarray(eye_xyz_m, dtype=np.float64)
        view = pybullet.computeViewMatrix(eye.tolist(), (eye + forward).tolist(), up.tolist())
        self._cull(eye_xyz_m, arc)
        proj = pybullet.computeProjectionMatrixFOV(
            fov=math.degrees(camera.fov_rad), aspect=1.0, nearVal=NEAR_M, farVal=FAR_M
        )
        _, _, rgba, depth_buffer, _ = pybullet.getCameraImage(
            res,
            res,
            view,
            proj,
            renderer=pybullet.ER_TINY_RENDERER,
            lightAmbientCoeff=1.0,
            lightDiffuseCoeff=0.0,
            lightSpecularCoeff=0.0,
            shadow=0,
            physicsClientId=self._client,
        )
        albedo = np.asarray(rgba, dtype=np.float32).reshape(res, res, 4)[:, :, :3]
        depth = np.asarray(depth_buffer, dtype=np.float64).reshape(res, res)
        return _lamp(albedo, depth, camera)

    def ray_distances_m(
        self, origins_m: np.ndarray, directions: np.ndarray, max_range_m: float
    ) -> np.ndarray:
        """Distance along each ray to the first wall, or ``max_range_m`` if none."""
        directions = directions / np.linalg.norm(directions, axis=1, keepdims=True)
        ends = origins_m + directions * max_range_m
        if self.stream:  # every wall a ray may reach is built first
            points = np.concatenate([origins_m, ends])[:, :2]
            self._pieces.near(points.min(axis=0), points.max(axis=0))
        hits = pybullet.rayTestBatch(
            origins_m.tolist(), ends.tolist(), physicsClientId=self._client
        )
        fractions = np.array([h[2] if h[0] >= 0 else 1.0 for h in hits])
        return fractions * max_range_m


def body_rotation(heading_rad: float, roll_rad: float, pitch_rad: float) -> np.ndarray:
    """World-from-body rotation of a robot: heading about z, then pitch about its
    y (left) axis, nose down positive, then roll about its x (forward) axis."""
    cz, sz = math.cos(heading_rad), math.sin(heading_rad)
    cp, sp = math.cos(pitch_rad), math.sin(pitch_rad)
    cr, sr = math.cos(roll_rad), math.sin(roll_rad)
    yaw = np.array([[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]])
    pitch = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    roll = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    matrix: np.ndarray = yaw @ pitch @ roll
    return matrix


@functools.lru_cache(maxsize=4)
def _pixel_rays(resolution_px: int, fov_rad: float) -> np.ndarray:
    """Eye-frame ray of every pixel, scaled to unit depth (camera looks along -z)."""
    half = math.tan(fov_rad / 2.0)
    coords = ((np.arange(resolution_px) + 0.5) / resolution_px * 2.0 - 1.0) * half
    xs, ys = np.meshgrid(coords, -coords)
    rays = np.stack([xs, ys, -np.ones_like(xs)], -1).astype(np.float32)
    rays.setflags(write=False)
    return rays


def _lamp(albedo: np.ndarray, depth_buffer: np.ndarray, camera: CameraSpec) -> np.ndarray:
    """Light an albedo image: uniform light plus ``lamp_strength`` of a lamp at the camera."""
    if camera.lamp_strength == 0.0:
        out = albedo.copy()
        out[depth_buffer >= 1.0] = 0.0  # nothing there (a hole would show as black)
        flat: np.ndarray = np.clip(out, 0.0, 255.0).astype(np.uint8)
        return flat
    z = (FAR_M * NEAR_M / (FAR_M - (FAR_M - NEAR_M) * depth_buffer)).astype(np.float32)
    rays = _pixel_rays(camera.resolution_px, camera.fov_rad)
    points = rays * z[..., None]
    # Surface normal from neighbouring points (forward differences, last row/column
    # repeated); the lamp's light falls on it at the angle to the pixel's ray.
    dx = np.empty_like(points)
    dy = np.empty_like(points)
    dx[:, :-1] = points[:, 1:] - points[:, :-1]
    dx[:, -1] = dx[:, -2]
    dy[:-1] = points[1:] - points[:-1]
    dy[-1] = dy[-2]
    normal = np.cross(dx, dy)
    dist = np.sqrt(np.einsum("ijk,ijk->ij", points, points))
    cosine = np.abs(np.einsum("ijk,ijk->ij", normal, points)) / (
        np.sqrt(np.einsum("ijk,ijk->ij", normal, normal)) * dist + 1e-12
    )
    lamp = np.minimum((LAMP_REFERENCE_M / dist) ** 2, 1.3) * (0.3 + 0.7 * cosine)
    light = (1.0 - camera.lamp_strength) + camera.lamp_strength * lamp
    light[depth_buffer >= 1.0] = 0.0  # nothing there: the dark beyond the lamp's reach
    lit: np.ndarray = np.clip(albedo * light[..., None], 0.0, 255.0).astype(np.uint8)
    return lit
