"""The room queries (signed distance, ray casts, ray fans) on six rooms of every task, and the
path planner's segment clearance test on one of them."""

import numpy as np

from vrloco_env.tasks import make_layout
from vrloco_env.world import RoomBatch, RoomConfig
from vrloco_env.world.geometry import _segments_clear


def _queries():
    lays = [
        make_layout(
            ("approach", "avoid", "interact")[s % 3], RoomConfig(), np.random.default_rng(s)
        )
        for s in range(6)
    ]
    batch = RoomBatch(lays)
    rng = np.random.default_rng(1)
    o = rng.uniform(-4.0, 4.0, (6, 30, 2))  # inside solids, outside, beyond the walls
    a = rng.uniform(-np.pi, np.pi, (6, 30))
    return {
        "signed_distance": batch.signed_distance(o),
        "ray_cast": batch.ray_cast(o, a, 12.0),
        "ray_fan": batch.ray_fan(o[:, 0], a[:, 0], np.linspace(-1.0, 1.0, 7), 8.0),
        # segments across the room: clear of a disc of 0.3 m, or not
        "segments_clear": _segments_clear(lays[1]._packed, o[1], o[2], 40, 0.3),
    }


CASES = {"world_queries": _queries}
