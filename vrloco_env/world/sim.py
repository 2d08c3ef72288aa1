"""The one thin PyBullet wrapper of vrloco: it owns the client and names the bodies it creates.

Nothing else in the package imports ``pybullet``. The world is static and kinematic: walls,
obstacles and markers never move, avatars (the users' virtual bodies) are teleported every step
with :meth:`Simulation.set_poses`, and the per-step queries — rays from the virtual heads and
avatar contacts — are batched across every user sharing the world. Gravity is irrelevant and
``stepSimulation`` is never called.

Frames and units: world ENU (x east, y north, z up), positions in metres, yaw in radians
counter-clockwise about +z (:mod:`estimators.rotations`). PyBullet's quaternions are scalar-last
``[x, y, z, w]``; the conversion happens here and nowhere else.

Engineering decisions (measured with pybullet 3.2.7, see ``benchmarks/bench_sim.py``):

* **Avatars are dynamic bodies that are never stepped.** Bullet's dispatcher skips every pair of
  static (mass 0) objects, so a mass-0 avatar never reports a contact with a mass-0 wall. Avatars
  therefore get a nominal 1 kg; with no ``stepSimulation`` the mass has no effect.
* **Collision filter groups.** Static solids are in group ``GROUP_WORLD`` and avatars in
  ``GROUP_AVATAR`` whose mask holds only ``GROUP_WORLD``: avatars touch the static world but never
  each other. Rays carry Bullet's default group 1 and are cast with mask ``GROUP_WORLD``, so they
  never stop on an avatar (a ray from a head inside its own capsule would otherwise hit it).
* **Contacts** come from one ``performCollisionDetection`` and one ``getContactPoints`` for the
  whole world. Bullet keeps manifold points up to its contact-breaking threshold (0.02 m) *apart*;
  a body counts as touching only where the signed distance is ``<= contact_tolerance``. Each
  candidate pair is then confirmed with ``getClosestPoints`` (only pairs in contact, so a few per
  step): the broadphase drops stale pairs lazily, and a teleported body can keep a stale manifold
  point with a meaningless negative distance.
* **Rays** go through ``rayTestBatch``, chunked below ``MAX_RAY_INTERSECTION_BATCH_SIZE`` (a batch
  of exactly that size silently returns nothing in 3.2.7). They cost 2-3 µs each on one core
  whatever the world size (Bullet's GJK ray cast per shape hit), so 256 users x 16 rays take
  ~13 ms a step: over the vector env's whole 12.8 ms budget at 20,000 user-steps/s. Bullet's ray
  cast on cylinders is within ~1 mm of the true surface.
  :class:`vrloco_env.world.room_batch.RoomBatch` casts the same rays analytically ~30x faster.
* **Creating bodies** costs 100-250 µs each and grows with the number of bodies in the world
  (500-600 µs for a visual-only body); :meth:`Simulation.create_compound` makes all of a room's
  walls, or obstacles, one body.
* **Memory.** Removing a body does not give its memory back (about 1 KB per body, 3.5 KB with its
  own collision shape; ``removeCollisionShape`` refuses a shape once a body has used it); only
  ``resetSimulation`` frees it. A vector env rebuilds one room on every sub-env reset, so after
  ``compact_after`` removals the wrapper rebuilds the world from the recorded specs of the live
  bodies, keeping every body id unchanged (:meth:`Simulation.compact`).
* **GUI without a display.** PyBullet's GUI calls ``exit(1)`` from C when it cannot open an X
  display, killing the Python process; the wrapper checks for a display first and raises.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import math
import os
import sys
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.rotations import quat_from_ypr, quat_to_ypr


@contextlib.contextmanager
def _quiet_native_output() -> Iterator[None]:
    """Silence what native code prints to the process's stdout and stderr (PyBullet prints its
    build time on import and ``argv[0]=`` on connecting, from C, in every process)."""
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    try:
        saved = (os.dup(1), os.dup(2))
    except OSError:  # no file descriptors to redirect (an embedded interpreter)
        yield
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    libc = ctypes.CDLL(None)
    try:
        os.dup2(devnull, 1)
        os.dup2(devnull, 2)
        yield
    finally:
        libc.fflush(None)  # C's buffered output goes to /dev/null, not to the restored streams
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in (*saved, devnull):
            os.close(fd)


with _quiet_native_output():
    import pybullet
    from pybullet_utils.bullet_client import BulletClient

__all__ = [
    "GROUP_AVATAR",
    "GROUP_WORLD",
    "RENDER_MODES",
    "Simulation",
    "display_available",
]

#: Render modes accepted by :class:`Simulation` (Gymnasium's names).
RENDER_MODES = (None, "rgb_array", "human")

#: Collision group of static solids (walls, obstacles, pedestals): hit by rays, touched by avatars.
GROUP_WORLD = 1
#: Collision group of avatars: they touch ``GROUP_WORLD`` only (not each other, not rays).
GROUP_AVATAR = 2

#: Largest ray batch handed to one ``rayTestBatch`` call (PyBullet's limit minus one: a batch of
#: exactly ``MAX_RAY_INTERSECTION_BATCH_SIZE`` rays returns an empty result in pybullet 3.2.7).
_RAY_CHUNK = pybullet.MAX_RAY_INTERSECTION_BATCH_SIZE - 1
#: Nominal avatar mass in kg; only its being non-zero matters (see the module docstring).
_AVATAR_MASS = 1.0
_DEFAULT_RGBA = (0.6, 0.6, 0.6, 1.0)


def display_available() -> bool:
    """Whether PyBullet's GUI can open a window here.

    On Linux PyBullet's GUI needs an X server (``DISPLAY``, possibly XWayland); this opens and
    closes a connection with libX11 to make sure. Other platforms use their native window system.

    Returns:
        True if a GUI connection can be attempted safely.
    """
    if not sys.platform.startswith("linux"):
        return True
    if not os.environ.get("DISPLAY"):
        return False
    lib = ctypes.util.find_library("X11")
    if lib is None:
        return False
    try:
        x11 = ctypes.CDLL(lib)
        x11.XOpenDisplay.argtypes = [ctypes.c_char_p]
        x11.XOpenDisplay.restype = ctypes.c_void_p
        x11.XCloseDisplay.argtypes = [ctypes.c_void_p]
        display = x11.XOpenDisplay(None)
        if not display:
            return False
        x11.XCloseDisplay(display)
    except OSError:
        return False
    return True


@dataclass(frozen=True)
class _Part:
    """One primitive of a body, placed in the body frame."""

    kind: str  # "box", "cylinder", "capsule", "sphere"
    dims: tuple[float, ...]  # box: half extents (3); cylinder/capsule: radius, height; sphere: r
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)  # m, in the body frame
    yaw: float = 0.0  # rad, about the body's z


@dataclass(frozen=True)
class _BodySpec:
    """What is needed to create a body again (for :meth:`Simulation.compact`)."""

    name: str
    parts: tuple[_Part, ...]
    rgba: tuple[float, float, float, float]
    collide: bool
    avatar: bool


def _shape_args(part: _Part, visual: bool) -> tuple[int, dict[str, Any]]:
    """PyBullet geometry type and keyword arguments of one part."""
    if part.kind == "box":
        return pybullet.GEOM_BOX, {"halfExtents": list(part.dims)}
    if part.kind == "sphere":
        return pybullet.GEOM_SPHERE, {"radius": part.dims[0]}
    radius, height = part.dims
    # PyBullet's capsule length is that of the segment between the cap centres; visual shapes
    # call the length "length", collision shapes "height".
    length = height if part.kind == "cylinder" else height - 2.0 * radius
    geom = pybullet.GEOM_CYLINDER if part.kind == "cylinder" else pybullet.GEOM_CAPSULE
    return geom, {"radius": radius, ("length" if visual else "height"): length}


def _finite(name: str, value: ArrayLike, shape: tuple[int | None, ...]) -> NDArray[np.float64]:
    """``value`` as a finite float array of ``shape`` (None = any length), or a ValueError."""
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be numeric, got {value!r}") from exc
    if a.ndim != len(shape) or any(
        s is not None and s != n for s, n in zip(shape, a.shape, strict=True)
    ):
        want = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ")"
        raise ValueError(f"{name} must have shape {want}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be finite, got {a}")
    return a


def _positive(name: str, value: float) -> float:
    v = float(value)
    if not (math.isfinite(v) and v > 0.0):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    return v


def _rgba(name: str, value: ArrayLike) -> tuple[float, float, float, float]:
    a = _finite(name, value, (4,))
    if np.any((a < 0.0) | (a > 1.0)):
        raise ValueError(f"{name} components must lie in [0, 1], got {a}")
    return (float(a[0]), float(a[1]), float(a[2]), float(a[3]))


def _yaw_to_xyzw(yaw: NDArray[np.float64]) -> NDArray[np.float64]:
    """PyBullet quaternions ``(N, 4)`` ``[x, y, z, w]`` of yaws ``(N,)`` about +z (rad)."""
    ypr = np.zeros((yaw.shape[0], 3))
    ypr[:, 0] = yaw
    return quat_from_ypr(ypr)[:, [1, 2, 3, 0]]


class Simulation:
    """A PyBullet world of named static solids, visual markers and kinematic avatars.

    Args:
        render_mode: ``None`` or ``"rgb_array"`` (headless ``DIRECT`` connection; images come from
            the TinyRenderer) or ``"human"`` (a ``GUI`` window; needs a display).
        ray_threads: threads for ``rayTestBatch``: 1 = single core (default: the bench machine
            is shared), 0 = let Bullet decide, n >= 2 = n threads.
        contact_tolerance: signed distance (m) at or below which two bodies count as touching;
            0 = touching or penetrating. Must lie in [-0.01, 0.01] (Bullet keeps manifold points
            only up to 0.02 m apart).
        compact_after: number of removed bodies after which the world is rebuilt to free their
            memory (about 3.5 KB each, see the module docstring); 0 disables it.

    Raises:
        ValueError: on a bad argument.
        RuntimeError: if ``"human"`` is asked for and no display is available, or the
            connection fails.
    """

    def __init__(
        self,
        render_mode: str | None = None,
        ray_threads: int = 1,
        contact_tolerance: float = 0.0,
        compact_after: int = 20_000,
    ) -> None:
        self._client: BulletClient | None = None
        if render_mode not in RENDER_MODES:
            raise ValueError(f"render_mode must be one of {RENDER_MODES}, got {render_mode!r}")
        if int(ray_threads) != ray_threads or ray_threads < 0:
            raise ValueError(f"ray_threads must be an integer >= 0, got {ray_threads!r}")
        tol = float(contact_tolerance)
        if not (math.isfinite(tol) and -0.01 <= tol <= 0.01):
            raise ValueError(f"contact_tolerance must lie in [-0.01, 0.01] m, got {tol!r}")
        if int(compact_after) != compact_after or compact_after < 0:
            raise ValueError(f"compact_after must be an integer >= 0, got {compact_after!r}")
        self.render_mode = render_mode
        self.ray_threads = int(ray_threads)
        self.contact_tolerance = tol
        self.compact_after = int(compact_after)
        self._gui = render_mode == "human"
        if self._gui and not display_available():
            raise RuntimeError(
                "render_mode='human' needs a display for PyBullet's GUI window, and none is "
                "available (DISPLAY is unset or the X server cannot be opened). Use "
                "render_mode='rgb_array' or None for headless runs."
            )
        mode = pybullet.GUI if self._gui else pybullet.DIRECT
        with _quiet_native_output():
            client = BulletClient(connection_mode=mode)
        if client._client < 0:
            kind = "GUI" if self._gui else "DIRECT"
            raise RuntimeError(
                f"could not connect to PyBullet in {kind} mode (PyBullet allows one GUI "
                "connection per process)"
            )
        self._client = client
        self._pid = os.getpid()
        self._ids: dict[str, int] = {}
        self._names: dict[int, str] = {}
        self._specs: dict[int, _BodySpec] = {}
        self._removed = 0
        self._configure()

    def _configure(self) -> None:
        """World settings, applied after connecting and after every ``resetSimulation``."""
        c = self._client
        c.setGravity(0.0, 0.0, 0.0)
        if self._gui:
            c.configureDebugVisualizer(pybullet.COV_ENABLE_GUI, 0)
        self._reset_pose = c.resetBasePositionAndOrientation

    @property
    def client(self) -> BulletClient:
        """The PyBullet client; raises if the simulation is closed."""
        if self._client is None:
            raise RuntimeError("the Simulation is closed")
        return self._client

    @property
    def is_open(self) -> bool:
        """Whether :meth:`close` has not been called yet."""
        return self._client is not None

    # ------------------------------------------------------------------ bodies by name

    @property
    def names(self) -> list[str]:
        """Names of the live bodies, in creation order."""
        return list(self._ids)

    def __contains__(self, name: object) -> bool:
        return name in self._ids

    def body_id(self, name: str) -> int:
        """The PyBullet id of the body called ``name``."""
        try:
            return self._ids[name]
        except KeyError:
            raise KeyError(f"no body named {name!r}") from None

    def name_of(self, body_id: int) -> str:
        """The name of the body with PyBullet id ``body_id``."""
        try:
            return self._names[int(body_id)]
        except KeyError:
            raise KeyError(f"no body with id {body_id}") from None

    def _create(self, spec: _BodySpec, position: Sequence[float], orn: Sequence[float]) -> int:
        """Create the PyBullet body described by ``spec`` and return its id."""
        c = self.client
        visual = not spec.collide
        if len(spec.parts) == 1 and spec.parts[0].offset == (0.0, 0.0, 0.0):
            geom, kwargs = _shape_args(spec.parts[0], visual)
            if visual:
                shape = c.createVisualShape(geom, rgbaColor=list(spec.rgba), **kwargs)
            else:
                shape = c.createCollisionShape(geom, **kwargs)
        else:  # a compound: one body, one broadphase entry, many primitives
            args: dict[str, list[Any]] = {
                "shapeTypes": [],
                "radii": [],
                "halfExtents": [],
                "lengths": [],
            }
            for part in spec.parts:
                geom, kwargs = _shape_args(part, True)
                args["shapeTypes"].append(geom)
                args["radii"].append(kwargs.get("radius", 0.0))
                args["halfExtents"].append(kwargs.get("halfExtents", [0.0, 0.0, 0.0]))
                args["lengths"].append(kwargs.get("length", 0.0))
            frames = [list(p.offset) for p in spec.parts]
            quats = _yaw_to_xyzw(np.array([p.yaw for p in spec.parts])).tolist()
            if visual:
                shape = c.createVisualShapeArray(
                    **args,
                    visualFramePositions=frames,
                    visualFrameOrientations=quats,
                    rgbaColors=[list(spec.rgba)] * len(spec.parts),
                )
            else:
                shape = c.createCollisionShapeArray(
                    **args, collisionFramePositions=frames, collisionFrameOrientations=quats
                )
        if visual:
            return int(c.createMultiBody(0.0, -1, shape, list(position), list(orn)))
        mass = _AVATAR_MASS if spec.avatar else 0.0
        body = int(c.createMultiBody(mass, shape, -1, list(position), list(orn)))
        group = GROUP_AVATAR if spec.avatar else GROUP_WORLD
        # Static solids accept Bullet's default group 1 so that rays (group 1) can hit them.
        mask = GROUP_WORLD if spec.avatar else (GROUP_AVATAR | GROUP_WORLD)
        c.setCollisionFilterGroupMask(body, -1, group, mask)
        # Without a visual shape PyBullet draws the collision shape; colour it.
        c.changeVisualShape(body, -1, rgbaColor=list(spec.rgba))
        return body

    def _add(self, spec: _BodySpec, position: ArrayLike, yaw: float = 0.0) -> int:
        if not isinstance(spec.name, str) or not spec.name:
            raise ValueError(f"name must be a non-empty string, got {spec.name!r}")
        if spec.name in self._ids:
            raise ValueError(f"a body named {spec.name!r} already exists")
        pos = _finite("position", position, (3,))
        yaw_a = _finite("yaw", [yaw], (1,))
        body = self._create(spec, pos.tolist(), _yaw_to_xyzw(yaw_a)[0].tolist())
        self._ids[spec.name] = body
        self._names[body] = spec.name
        self._specs[body] = spec
        return body

    def create_box(
        self,
        name: str,
        half_extents: ArrayLike,
        position: ArrayLike,
        yaw: float = 0.0,
        rgba: ArrayLike = _DEFAULT_RGBA,
        collide: bool = True,
    ) -> int:
        """Create a static box (a wall, an obstacle, a pedestal).

        Args:
            name: unique body name.
            half_extents: ``(3,)`` half sizes along the box's own x, y, z (m), each > 0.
            position: ``(3,)`` centre in the world (m).
            yaw: rotation about +z (rad).
            rgba: colour, components in [0, 1].
            collide: False makes a visual-only body (no rays, no contacts).

        Returns:
            The PyBullet body id.
        """
        he = _finite("half_extents", half_extents, (3,))
        if np.any(he <= 0.0):
            raise ValueError(f"half_extents must be > 0 m, got {he}")
        part = _Part("box", tuple(map(float, he)))
        spec = _BodySpec(name, (part,), _rgba("rgba", rgba), bool(collide), False)
        return self._add(spec, position, yaw)

    def create_cylinder(
        self,
        name: str,
        radius: float,
        height: float,
        position: ArrayLike,
        rgba: ArrayLike = _DEFAULT_RGBA,
        collide: bool = True,
    ) -> int:
        """Create a static upright cylinder (an obstacle, a floor disc when ``collide=False``).

        Args:
            name: unique body name.
            radius: radius (m), > 0.
            height: full height along +z (m), > 0.
            position: ``(3,)`` centre in the world (m).
            rgba: colour, components in [0, 1].
            collide: False makes a visual-only body.

        Returns:
            The PyBullet body id.
        """
        dims = (_positive("radius", radius), _positive("height", height))
        part = _Part("cylinder", dims)
        spec = _BodySpec(name, (part,), _rgba("rgba", rgba), bool(collide), False)
        return self._add(spec, position)

    def create_compound(
        self,
        name: str,
        boxes: Sequence[tuple[ArrayLike, ArrayLike, float]] = (),
        cylinders: Sequence[tuple[float, float, ArrayLike]] = (),
        position: ArrayLike = (0.0, 0.0, 0.0),
        rgba: ArrayLike = _DEFAULT_RGBA,
        collide: bool = True,
    ) -> int:
        """Create one static body made of many boxes and upright cylinders (e.g. all of a room's
        walls, or all its obstacles).

        One body instead of one per primitive: PyBullet's ``createMultiBody`` costs grow with the
        number of bodies in the world (about 100 µs each at 500 bodies, 200 µs at 2,500), so a
        room built from a few compounds is several times faster to (re)build. Rays and contacts
        report the compound, not the primitive hit; the whole compound has one colour.

        Args:
            name: unique body name.
            boxes: ``(half_extents (3,), center (3,), yaw)`` per box, in the body frame (m, rad).
            cylinders: ``(radius, height, center (3,))`` per cylinder, in the body frame (m).
            position: ``(3,)`` body origin in the world (m).
            rgba: colour, components in [0, 1].
            collide: False makes a visual-only body.

        Returns:
            The PyBullet body id.
        """
        parts = []
        for i, (he, center, yaw) in enumerate(boxes):
            h = _finite(f"boxes[{i}] half_extents", he, (3,))
            if np.any(h <= 0.0):
                raise ValueError(f"boxes[{i}] half_extents must be > 0 m, got {h}")
            c = _finite(f"boxes[{i}] center", center, (3,))
            y = float(_finite(f"boxes[{i}] yaw", [yaw], (1,))[0])
            parts.append(_Part("box", tuple(map(float, h)), tuple(map(float, c)), y))
        for i, (radius, height, center) in enumerate(cylinders):
            dims = (
                _positive(f"cylinders[{i}] radius", radius),
                _positive(f"cylinders[{i}] height", height),
            )
            c = _finite(f"cylinders[{i}] center", center, (3,))
            parts.append(_Part("cylinder", dims, tuple(map(float, c))))
        if not parts:
            raise ValueError("a compound needs at least one box or cylinder")
        spec = _BodySpec(name, tuple(parts), _rgba("rgba", rgba), bool(collide), False)
        return self._add(spec, position)

    def create_capsule(
        self,
        name: str,
        radius: float,
        height: float,
        position: ArrayLike,
        rgba: ArrayLike = (0.2, 0.4, 0.9, 1.0),
    ) -> int:
        """Create an avatar: an upright capsule that touches the static world, not other avatars.

        Args:
            name: unique body name.
            radius: radius (m), > 0.
            height: full height including both caps (m), > 2 * radius.
            position: ``(3,)`` centre in the world (m); standing on the floor means
                ``z = height / 2``.
            rgba: colour, components in [0, 1].

        Returns:
            The PyBullet body id (move it with :meth:`set_poses`).
        """
        r, h = _positive("radius", radius), _positive("height", height)
        if h <= 2.0 * r:
            raise ValueError(f"height must be > 2 * radius = {2 * r} m, got {h}")
        spec = _BodySpec(name, (_Part("capsule", (r, h)),), _rgba("rgba", rgba), True, True)
        return self._add(spec, position)

    def create_marker(
        self, name: str, radius: float, position: ArrayLike, rgba: ArrayLike = (0.1, 0.8, 0.2, 1.0)
    ) -> int:
        """Create a visual-only sphere (goal or target marker): no rays, no contacts.

        Args:
            name: unique body name.
            radius: radius (m), > 0.
            position: ``(3,)`` centre in the world (m).
            rgba: colour, components in [0, 1].

        Returns:
            The PyBullet body id.
        """
        part = _Part("sphere", (_positive("radius", radius),))
        spec = _BodySpec(name, (part,), _rgba("rgba", rgba), False, False)
        return self._add(spec, position)

    def create_floor(
        self,
        name: str,
        center: ArrayLike,
        half_extents: ArrayLike,
        rgba: ArrayLike = (0.85, 0.85, 0.8, 1.0),
    ) -> int:
        """Create a visual-only floor tile whose top face lies at z = 0 (for rendering only).

        Args:
            name: unique body name.
            center: ``(2,)`` centre of the tile in the world (m).
            half_extents: ``(2,)`` half sizes along x and y (m), > 0.
            rgba: colour, components in [0, 1].

        Returns:
            The PyBullet body id.
        """
        c = _finite("center", center, (2,))
        he = _finite("half_extents", half_extents, (2,))
        thickness = 0.005  # m, half thickness of the tile
        return self.create_box(
            name, [he[0], he[1], thickness], [c[0], c[1], -thickness], rgba=rgba, collide=False
        )

    def remove_body(self, name: str) -> None:
        """Remove the body called ``name`` (its memory is freed at the next compaction)."""
        body = self.body_id(name)
        self.client.removeBody(body)
        del self._ids[name], self._names[body], self._specs[body]
        self._removed += 1
        if self.compact_after and self._removed >= self.compact_after:
            self.compact()

    def remove_prefix(self, prefix: str) -> None:
        """Remove every body whose name starts with ``prefix`` (e.g. one room of a vector env)."""
        for name in [n for n in self._ids if n.startswith(prefix)]:
            self.remove_body(name)

    def clear(self) -> None:
        """Remove every body (``resetSimulation``: all memory is freed)."""
        self.client.resetSimulation()
        self._configure()
        self._ids.clear()
        self._names.clear()
        self._specs.clear()
        self._removed = 0

    def compact(self) -> None:
        """Rebuild the world from the live bodies' specs to free removed bodies' memory.

        Every live body keeps its id, name, shape, colour, collision group and current pose.
        Called automatically after ``compact_after`` removals.
        """
        c = self.client
        poses = {b: c.getBasePositionAndOrientation(b) for b in self._specs}
        specs = dict(self._specs)
        ids = dict(self._ids)
        self.clear()
        top = max(specs, default=-1)
        fillers = []
        for want in range(top + 1):
            if want in specs:
                got = self._create(specs[want], *poses[want])
            else:  # an id that was free: hold it with an empty body, removed below
                got = int(c.createMultiBody(0.0, -1, -1, [0.0, 0.0, 0.0]))
                fillers.append(got)
            if got != want:
                raise RuntimeError(f"compaction gave body id {got} instead of {want}")
        for body in fillers:
            c.removeBody(body)
        self._ids = ids
        self._names = {b: n for n, b in ids.items()}
        self._specs = specs

    @contextlib.contextmanager
    def no_rendering(self) -> Iterator[None]:
        """Pause GUI rendering inside the block (bulk creation is much faster); no-op headless."""
        if not self._gui:
            yield
            return
        self.client.configureDebugVisualizer(pybullet.COV_ENABLE_RENDERING, 0)
        try:
            yield
        finally:
            if self._client is not None:
                self._client.configureDebugVisualizer(pybullet.COV_ENABLE_RENDERING, 1)

    # ------------------------------------------------------------------ batched per-step calls

    def set_poses(self, body_ids: ArrayLike, positions: ArrayLike, yaws: ArrayLike) -> None:
        """Teleport N bodies (avatars) at once.

        PyBullet has no batched base-pose setter, so this is one ``resetBasePositionAndOrientation``
        per body from pre-converted lists (about 1 µs each, ``benchmarks/bench_sim.py``).

        Args:
            body_ids: ``(N,)`` PyBullet ids.
            positions: ``(N, 3)`` base positions in the world (m).
            yaws: ``(N,)`` yaw about +z (rad).
        """
        ids = np.asarray(body_ids)
        if ids.ndim != 1 or not np.issubdtype(ids.dtype, np.integer):
            raise ValueError(f"body_ids must be a 1-D integer array, got {ids.dtype} {ids.shape}")
        n = ids.shape[0]
        pos = _finite("positions", positions, (n, 3))
        quat = _yaw_to_xyzw(_finite("yaws", yaws, (n,)))
        if self._client is None:
            raise RuntimeError("the Simulation is closed")
        reset = self._reset_pose
        for body, p, q in zip(ids.tolist(), pos.tolist(), quat.tolist(), strict=True):
            reset(body, p, q)

    def get_poses(self, body_ids: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Base positions ``(N, 3)`` (m) and yaws ``(N,)`` (rad) of N bodies."""
        ids = np.asarray(body_ids, dtype=np.int64).reshape(-1)
        c = self.client
        states = [c.getBasePositionAndOrientation(b) for b in ids.tolist()]
        pos = np.array([s[0] for s in states], dtype=np.float64).reshape(-1, 3)
        xyzw = np.array([s[1] for s in states], dtype=np.float64).reshape(-1, 4)
        return pos, quat_to_ypr(xyzw[:, [3, 0, 1, 2]])[:, 0]

    def ray_test(
        self, origins: ArrayLike, ends: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """Cast R rays against the static world (avatars and visual-only bodies are ignored).

        One ``rayTestBatch`` per 16,383 rays.

        Args:
            origins: ``(R, 3)`` ray starts in the world (m).
            ends: ``(R, 3)`` ray ends in the world (m).

        Returns:
            ``fraction`` ``(R,)``: hit distance / ray length in [0, 1], 1 where nothing is hit;
            ``hit_body`` ``(R,)``: PyBullet id of the body hit, -1 where nothing is hit.
        """
        o = _finite("origins", origins, (None, 3))
        e = _finite("ends", ends, (o.shape[0], 3))
        c = self.client
        n = o.shape[0]
        fraction = np.ones(n)
        hit = np.full(n, -1, dtype=np.int64)
        for start in range(0, n, _RAY_CHUNK):
            stop = min(start + _RAY_CHUNK, n)
            res = c.rayTestBatch(
                o[start:stop],
                e[start:stop],
                numThreads=self.ray_threads,
                collisionFilterMask=GROUP_WORLD,
            )
            hit[start:stop] = np.fromiter((r[0] for r in res), np.int64, stop - start)
            fraction[start:stop] = np.fromiter((r[2] for r in res), np.float64, stop - start)
        fraction[hit < 0] = 1.0
        return fraction, hit

    def contacts(self, body_ids: ArrayLike) -> NDArray[np.bool_]:
        """Whether each of N bodies touches another collidable body now (one collision pass).

        Args:
            body_ids: ``(N,)`` PyBullet ids (typically the avatars).

        Returns:
            ``(N,)`` bool: True where the body's signed distance to some other collidable body is
            ``<= contact_tolerance``.
        """
        ids = np.asarray(body_ids)
        if ids.ndim != 1 or not np.issubdtype(ids.dtype, np.integer):
            raise ValueError(f"body_ids must be a 1-D integer array, got {ids.dtype} {ids.shape}")
        c = self.client
        c.performCollisionDetection()
        points = c.getContactPoints()
        if not points:
            return np.zeros(ids.shape[0], dtype=bool)
        # Contact point tuple: (flag, bodyA, bodyB, linkA, linkB, posA, posB, normal, distance,...)
        tol = self.contact_tolerance
        pairs = {(p[1], p[2]) for p in points if p[8] <= tol}
        # Confirm each candidate pair afresh: the broadphase drops pairs that stopped overlapping
        # lazily, and a stale manifold point of a teleported body can survive the refresh with a
        # meaningless negative distance (2 false contacts in 9,000 random teleports here).
        touching = [
            body
            for a, b in pairs
            if any(q[8] <= tol for q in c.getClosestPoints(a, b, max(tol, 0.0) + 1e-3))
            for body in (a, b)
        ]
        return np.isin(ids, np.asarray(touching, dtype=np.int64))

    # ------------------------------------------------------------------ images

    def camera_image(
        self,
        eye: ArrayLike,
        target: ArrayLike,
        up: ArrayLike = (0.0, 0.0, 1.0),
        width: int = 160,
        height: int = 120,
        fov_deg: float = 90.0,
        near: float = 0.05,
        far: float = 30.0,
    ) -> NDArray[np.uint8]:
        """A pinhole camera image from the CPU TinyRenderer (works headless).

        Args:
            eye: ``(3,)`` camera position in the world (m).
            target: ``(3,)`` a point the camera looks at (m).
            up: ``(3,)`` the image's up direction in the world.
            width: image width in pixels (1..4096).
            height: image height in pixels (1..4096).
            fov_deg: vertical field of view in degrees, in (0, 180).
            near: near clipping distance (m), > 0.
            far: far clipping distance (m), > near.

        Returns:
            ``(height, width, 3)`` uint8 RGB.
        """
        eye_a = _finite("eye", eye, (3,))
        target_a = _finite("target", target, (3,))
        up_a = _finite("up", up, (3,))
        w, h = self._image_size(width, height)
        if not 0.0 < float(fov_deg) < 180.0:
            raise ValueError(f"fov_deg must lie in (0, 180) degrees, got {fov_deg!r}")
        near_f = _positive("near", near)
        if not float(far) > near_f:
            raise ValueError(f"far must be > near = {near_f} m, got {far!r}")
        if np.linalg.norm(target_a - eye_a) == 0.0:
            raise ValueError("target must differ from eye")
        c = self.client
        view = c.computeViewMatrix(eye_a.tolist(), target_a.tolist(), up_a.tolist())
        proj = c.computeProjectionMatrixFOV(float(fov_deg), w / h, near_f, float(far))
        _, _, rgba, _, _ = c.getCameraImage(w, h, view, proj, renderer=pybullet.ER_TINY_RENDERER)
        return np.asarray(rgba, dtype=np.uint8).reshape(h, w, 4)[:, :, :3].copy()

    def top_down_image(
        self,
        center: ArrayLike,
        half_size: float,
        width: int = 256,
        height: int = 256,
        camera_height: float = 200.0,
    ) -> NDArray[np.uint8]:
        """A near-orthographic map: a camera far above ``center`` looking down, +y up the image.

        The TinyRenderer draws nothing with an orthographic projection matrix, so this is a
        narrow-angle perspective camera ``camera_height`` m up; the top of a 2.5 m wall then
        appears ``2.5 / camera_height`` (1.25 %) larger than the floor.

        Args:
            center: ``(2,)`` world point at the image centre (m).
            half_size: half the world extent shown along the shorter image side (m), > 0.
            width: image width in pixels (1..4096).
            height: image height in pixels (1..4096).
            camera_height: camera altitude (m), > ``half_size``.

        Returns:
            ``(height, width, 3)`` uint8 RGB.
        """
        c2 = _finite("center", center, (2,))
        hs = _positive("half_size", half_size)
        cam_h = _positive("camera_height", camera_height)
        w, h = self._image_size(width, height)
        # The vertical FOV covers half_size on the shorter side.
        half_v = hs if h <= w else hs * h / w
        fov = 2.0 * math.degrees(math.atan(half_v / cam_h))
        return self.camera_image(
            [c2[0], c2[1], cam_h],
            [c2[0], c2[1], 0.0],
            (0.0, 1.0, 0.0),
            w,
            h,
            fov,
            cam_h - 10.0 if cam_h > 20.0 else cam_h / 2.0,
            cam_h + 1.0,
        )

    @staticmethod
    def _image_size(width: int, height: int) -> tuple[int, int]:
        for name, v in (("width", width), ("height", height)):
            if int(v) != v or not 1 <= int(v) <= 4096:
                raise ValueError(f"{name} must be an integer in [1, 4096] pixels, got {v!r}")
        return int(width), int(height)

    def place_gui_camera(
        self, target: ArrayLike, distance: float, yaw_deg: float, pitch_deg: float
    ) -> None:
        """Point the GUI window's camera (``render_mode="human"``; no-op headless).

        Args:
            target: ``(3,)`` point the camera orbits (m).
            distance: camera distance from ``target`` (m), > 0.
            yaw_deg: PyBullet camera yaw (deg).
            pitch_deg: PyBullet camera pitch (deg), negative looks down.
        """
        t = _finite("target", target, (3,))
        d = _positive("distance", distance)
        if self._gui:
            self.client.resetDebugVisualizerCamera(d, float(yaw_deg), float(pitch_deg), t.tolist())

    # ------------------------------------------------------------------ lifetime

    def close(self) -> None:
        """Disconnect; idempotent and safe from ``__del__`` and after a fork."""
        client, self._client = getattr(self, "_client", None), None
        if client is None or getattr(self, "_pid", None) != os.getpid():
            return
        with contextlib.suppress(Exception):
            client.disconnect()

    def __del__(self) -> None:
        with contextlib.suppress(Exception):
            self.close()

    def __reduce_ex__(self, protocol: object) -> Any:
        """Refuse ``copy``, ``copy.deepcopy`` and ``pickle``: the world lives in a PyBullet
        physics server this object is connected to, and a copy would share that connection
        (closing either would close both)."""
        raise TypeError(
            "a Simulation (a connection to a PyBullet physics server) cannot be copied or "
            "pickled; build a new Simulation and its bodies instead"
        )

    def __enter__(self) -> Simulation:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
