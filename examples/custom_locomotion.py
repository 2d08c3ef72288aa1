"""Plug your own locomotion model into vrloco: glide each step's length at a walking speed.

    python examples/custom_locomotion.py   # one walk with it, beside eq (17)'s jumps

A locomotion stage is built as ``Cls(batch_size, step_length)`` (m) and has, as
:class:`estimators.stages.Locomotion` says (``docs/protocols.md``):

* ``batch_size`` and the properties ``position`` (B, 2) m, ``heading`` (B,) rad and
  ``distance`` (B,) m;
* ``reset(mask, position=..., heading=...)``: restart the users of the (B,) boolean ``mask``
  at those (B, 2) positions and (B,) headings (the environment always passes all three);
* ``update(steps, yaw, dt)``: the (B,) new steps and walking yaw (rad) of a control step of
  ``dt`` s; returns the (B, 2) positions, finite and within 1e4 m of the room's origin.

``EstimatorConfig(locomotion="examples/custom_locomotion.py:GlideLocomotion")`` selects it.
"""

from __future__ import annotations

import numpy as np


class GlideLocomotion:
    """Each detected step adds ``step_length`` to the distance still to go, which the body covers
    at ``speed`` (m/s) along the walking yaw: no jump, and no distance lost when stopping."""

    def __init__(self, batch_size: int, step_length: float, speed: float = 1.4) -> None:
        self.batch_size, self.step_length, self.speed = batch_size, step_length, speed
        self._pos = np.zeros((batch_size, 2))
        self._heading = np.zeros(batch_size)
        self._distance = np.zeros(batch_size)
        self._to_go = np.zeros(batch_size)  # metres of detected steps not yet covered

    def reset(self, mask=None, position=None, heading=None) -> None:
        sel = np.ones(self.batch_size, bool) if mask is None else np.asarray(mask, bool)
        self._pos[sel] = 0.0 if position is None else np.asarray(position)[sel]
        self._heading[sel] = 0.0 if heading is None else np.asarray(heading)[sel]
        self._distance[sel] = self._to_go[sel] = 0.0

    def update(self, steps, yaw, dt: float, bearing=None) -> np.ndarray:
        self._to_go += self.step_length * np.asarray(steps, np.float64)
        ds = np.minimum(self._to_go, self.speed * dt)
        self._to_go -= ds
        self._distance += ds
        self._heading = np.broadcast_to(np.asarray(yaw, np.float64), (self.batch_size,)).copy()
        self._pos += ds[:, None] * np.stack([np.cos(self._heading), np.sin(self._heading)], -1)
        return self._pos.copy()

    @property
    def position(self) -> np.ndarray:
        return self._pos.copy()

    @property
    def heading(self) -> np.ndarray:
        return self._heading.copy()

    @property
    def distance(self) -> np.ndarray:
        return self._distance.copy()


if __name__ == "__main__":
    import gymnasium as gym

    import vrloco_env  # noqa: F401  (registers the ids)
    from vrloco_env.config import EstimatorConfig

    glide = f"{__file__}:GlideLocomotion"
    for name, locomotion in (("eq17", "eq17"), ("GlideLocomotion", glide)):
        env = gym.make("VRLoco-Approach-v0", estimators=EstimatorConfig(locomotion=locomotion))
        env.reset(seed=0)
        walk = np.array([0.8, 0.0, 0, 0, 0])
        path = np.array([env.step(walk)[-1]["position"] for _ in range(60)])
        moves = np.linalg.norm(np.diff(path, axis=0), axis=-1)
        print(f"{name:>15}: {moves.sum():.1f} m in 6 s, at most {moves.max():.2f} m in a step")
        env.close()
