"""The visual-inertial ESKF (prediction and update kernels) on a short noisy stream of two users:
a block of 1 m jumps (gate rejections, then forced frames), flipped and unnormalised measured
quaternions, missing frames, with and without the IMU sample at the reset, and the fixed,
diagonal Sage-Husa (with adaptive Q) and full Sage-Husa noise models."""

import numpy as np

from estimators.head_pose.visual_inertial import VioConfig, VisualInertialFilter
from estimators.rotations import GRAVITY, quat_from_rotvec


def _run(config: VioConfig, seed: int):
    def play():
        rng = np.random.default_rng(seed)
        b, n = 2, 60
        gyr = rng.normal(0.0, 0.5, (b, n, 3))
        acc = np.array([0.0, 0.0, GRAVITY]) + rng.normal(0.0, 0.5, (b, n, 3))
        frames = np.arange(4, n, 5)
        m = frames.size
        pos = np.array([0.0, 0.0, 1.7]) + rng.normal(0.0, 0.03, (b, m, 3))
        pos[:, 3:7, 0] += 1.0  # outliers: rejected, then forced after gate_max_consecutive
        quat = quat_from_rotvec(rng.normal(0.0, 0.02, (b, m, 3)))
        quat[:, ::4] *= -1.5  # any sign and norm
        valid = np.ones((b, m), dtype=bool)
        valid[1, ::3] = False
        pos[1, ::3] = np.nan
        f = VisualInertialFilter(b, 1000.0, config)
        held = seed % 2 == 1  # the IMU sample at the reset instant given, or not
        f.reset(
            [0.0, 0.0, 1.7],
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0, 0.0],
            gyr=gyr[:, 0] if held else None,
            acc=acc[:, 0] if held else None,
        )
        p, q, status = f.process(gyr, acc, frames, pos, quat, valid)
        return {
            "p": p,
            "q": q,
            "status": status,
            "P": f.P,
            "R": f.R,
            "q_scale": f.q_scale,
            "nis": f.nis,
            "counters": np.stack([f.updates, f.rejected, f.forced]),
        }

    return play


CASES = {
    "vio_fixed_forced": _run(VioConfig(gate_max_consecutive=2), 0),
    "vio_sage_husa_adapt_q": _run(
        VioConfig(adaptive="sage_husa", adapt_q=True, gate_max_consecutive=2), 1
    ),
    "vio_sage_husa_full": _run(
        VioConfig(adaptive="sage_husa", sage_husa_diagonal=False, r_prior_frames=0), 2
    ),
}
