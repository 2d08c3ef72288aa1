"""The world the users walk in: rooms, their geometry, path planning, PyBullet and pictures.

* :mod:`~vrloco_env.world.config`: :class:`RoomConfig`, the sizes and draw ranges of the rooms.
* :mod:`~vrloco_env.world.geometry`: the floor-standing primitives (:class:`Box`,
  :class:`Cylinder`) and the exact 2-D distance and ray-cast queries on them (numba kernels).
* :mod:`~vrloco_env.world.layout`: a drawn room (:class:`Layout`), the queries on one room, and the
  building blocks the tasks (:mod:`vrloco_env.tasks`) draw their rooms with.
* :mod:`~vrloco_env.world.planning`: the avatar's shortest collision-free path in a room.
* :mod:`~vrloco_env.world.room_batch`: :class:`RoomBatch`, the queries of N users in N rooms in
  one compiled call.
* :mod:`~vrloco_env.world.bodies`: :func:`build`, a layout's bodies in the PyBullet world.
* :mod:`~vrloco_env.world.sim`: :class:`~vrloco_env.world.sim.Simulation`, the only module that
  imports ``pybullet``; :mod:`~vrloco_env.world.render`: the top-down map (OpenCV). These two are
  imported from their modules, so that importing the world does not load PyBullet or OpenCV.

The names below are re-exported from their modules.
"""

from vrloco_env.world.bodies import COLORS, build
from vrloco_env.world.config import RoomConfig
from vrloco_env.world.geometry import Box, Cylinder, Solid, solid_distance
from vrloco_env.world.layout import (
    Layout,
    check_rng,
    finish_layout,
    no_layout_error,
    ray_cast_2d,
    room_bounds,
    scatter_obstacles,
    signed_distance,
    tile_origins,
)
from vrloco_env.world.room_batch import RoomBatch

__all__ = [
    "COLORS",
    "Box",
    "Cylinder",
    "Layout",
    "RoomBatch",
    "RoomConfig",
    "Solid",
    "build",
    "check_rng",
    "finish_layout",
    "no_layout_error",
    "ray_cast_2d",
    "room_bounds",
    "scatter_obstacles",
    "signed_distance",
    "solid_distance",
    "tile_origins",
]
