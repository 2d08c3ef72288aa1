"""The landmarks the head camera looks at: the walls' landmarks of a room layout
(:func:`layout_landmarks`) and a batch of them padded to one width (:func:`pad_landmarks`)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    from vrloco_env.world import Layout


__all__ = ["layout_landmarks", "pad_landmarks"]


def layout_landmarks(layout: Layout) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """A room's landmarks in the world and the inward normals of their walls.

    Args:
        layout: a :class:`vrloco_env.world.layout.Layout`; its landmarks lie on the inner wall faces
            (local frame), shifted here by ``layout.origin`` (use ``layout.with_origin((0, 0))``
            for the local frame).

    Returns:
        ``(points, normals)``: (K, 3) m and (K, 3) unit vectors pointing into the room. A landmark
        is assigned the wall face (of the interior ``bounds``) it is closest to.
    """
    lm = np.asarray(layout.landmarks, dtype=np.float64)
    xmin, xmax, ymin, ymax = layout.bounds
    gaps = np.stack([lm[:, 0] - xmin, xmax - lm[:, 0], lm[:, 1] - ymin, ymax - lm[:, 1]], axis=1)
    inward = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0]])
    normals = inward[np.argmin(np.abs(gaps), axis=1)]
    ox, oy = layout.origin
    return lm + np.array([ox, oy, 0.0]), normals


def pad_landmarks(
    points: Sequence[ArrayLike],
    normals: Sequence[ArrayLike] | None = None,
    width: int | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64] | None, NDArray[np.bool_]]:
    """Stack per-user landmark sets of different sizes into padded arrays for a batch.

    Args:
        points: B arrays (K_i, 3) m.
        normals: B arrays (K_i, 3), or None.
        width: K of the result, >= every K_i (default: the largest K_i).

    Returns:
        ``(landmarks (B, K, 3), normals (B, K, 3) or None, mask (B, K))``; padded rows are zeros
        with mask False (at the end of each row, so a batch reproduces single runs).
    """
    pts = [np.asarray(p, dtype=np.float64) for p in points]
    if len(pts) == 0:
        raise ValueError("points must hold at least one (K_i, 3) array")
    for i, p in enumerate(pts):
        if p.ndim != 2 or p.shape[1] != 3:
            raise ValueError(f"points[{i}] must be (K_i, 3) m, got {p.shape}")
    k_max = max(p.shape[0] for p in pts)
    k = k_max if width is None else int(width)
    if k < k_max:
        raise ValueError(f"width must be >= the largest K_i = {k_max}, got {width}")
    b = len(pts)
    out = np.zeros((b, k, 3))
    mask = np.zeros((b, k), dtype=bool)
    nrm = None
    if normals is not None:
        if len(normals) != b:
            raise ValueError(f"normals must hold B={b} arrays, got {len(normals)}")
        nrm = np.zeros((b, k, 3))
    for i, p in enumerate(pts):  # once per room change, not on the hot path
        out[i, : p.shape[0]] = p
        mask[i, : p.shape[0]] = True
        if nrm is not None:
            n = np.asarray(normals[i], dtype=np.float64)  # type: ignore[index]
            if n.shape != p.shape:
                raise ValueError(f"normals[{i}] must have shape {p.shape}, got {n.shape}")
            nrm[i, : p.shape[0]] = n
    return out, nrm, mask
