"""Analytic head trajectories with exact derivatives, shared by the helmet-tracking paper's
tests."""

import numpy as np

from estimators.rotations import GRAVITY, quat_from_ypr, quat_rotate_inverse

G_WORLD = np.array([0.0, 0.0, -GRAVITY])


def circle_motion(t: np.ndarray) -> dict[str, np.ndarray]:
    """Analytic motion: a 3 m circle at 1 m/s with head bob and sinusoidal yaw/pitch/roll.

    Returns exact position, velocity, world acceleration, attitude and body angular rate at the
    times ``t`` (s), from closed-form derivatives of ZYX Euler angles.
    """
    r, wc = 3.0, 1.0 / 3.0
    fb, ab = 1.8, 0.03  # head bob frequency (Hz) and amplitude (m)
    ph = wc * t
    wb = 2 * np.pi * fb
    p = np.stack([r * np.cos(ph), r * np.sin(ph), 1.7 + ab * np.sin(wb * t)], -1)
    v = np.stack([-r * wc * np.sin(ph), r * wc * np.cos(ph), ab * wb * np.cos(wb * t)], -1)
    a = np.stack(
        [-r * wc**2 * np.cos(ph), -r * wc**2 * np.sin(ph), -ab * wb**2 * np.sin(wb * t)], -1
    )
    wy, wp, wr = 2 * np.pi * 0.15, 2 * np.pi * 0.5, 2 * np.pi * 0.9
    yaw = ph + np.pi / 2 + 0.35 * np.sin(wy * t)
    pitch = 0.05 + 0.1 * np.sin(wp * t)
    roll = 0.05 * np.sin(wr * t)
    dyaw = wc + 0.35 * wy * np.cos(wy * t)
    dpitch = 0.1 * wp * np.cos(wp * t)
    droll = 0.05 * wr * np.cos(wr * t)
    q = quat_from_ypr(np.stack([yaw, pitch, roll], -1))
    w = np.stack(
        [
            droll - dyaw * np.sin(pitch),
            dpitch * np.cos(roll) + dyaw * np.cos(pitch) * np.sin(roll),
            -dpitch * np.sin(roll) + dyaw * np.cos(pitch) * np.cos(roll),
        ],
        -1,
    )
    f = quat_rotate_inverse(q, a - G_WORLD)
    return {"p": p, "v": v, "a": a, "q": q, "w": w, "f": f}
