"""What the head camera delivers (:class:`CameraFrames`) and its extraction and matching rates."""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

__all__ = ["CameraFrames", "extraction_rate", "matching_rate"]


class CameraFrames(NamedTuple):
    """What the head camera delivers for B users, N frames and K landmarks.

    Missing values are NaN in ``pixels`` / ``pixels_true`` and -1 in ``matched_id``, always with an
    explicit boolean mask beside them.

    Attributes:
        t: (B, N) frame times (mid-exposure), s, as passed to :meth:`HeadCamera.capture`.
        pixels: (B, N, K, 2) measured feature positions (u, v), px; NaN where not extracted.
        pixels_true: (B, N, K, 2) noiseless projections, px; NaN where not visible.
        visible: (B, N, K) bool, geometric visibility (module docstring, step 1).
        occluded: (B, N, K) bool, visible but under the occluder band.
        extracted: (B, N, K) bool, the detector found the feature (implies visible, not occluded).
        matched_id: (B, N, K) int64, landmark index (row of the landmark array) the matcher gave
            the feature: k when right, another row when wrong, -1 when not extracted.
        blur_px: (B, N, K) blur length of each landmark's image, px (0 where not visible).
        occluder: (B, N, 2) the occluder band's [u_min, u_max], px; NaN without an occluder.
        n_visible: (B, N) int64 visible landmarks per frame.
        n_extracted: (B, N) int64 extracted features per frame.
        n_correct: (B, N) int64 extracted features matched to their own landmark.
    """

    t: NDArray[np.float64]
    pixels: NDArray[np.float64]
    pixels_true: NDArray[np.float64]
    visible: NDArray[np.bool_]
    occluded: NDArray[np.bool_]
    extracted: NDArray[np.bool_]
    matched_id: NDArray[np.int64]
    blur_px: NDArray[np.float64]
    occluder: NDArray[np.float64]
    n_visible: NDArray[np.int64]
    n_extracted: NDArray[np.int64]
    n_correct: NDArray[np.int64]

    @property
    def correct(self) -> NDArray[np.bool_]:
        """(B, N, K) bool: extracted and matched to its own landmark."""
        k = np.arange(self.matched_id.shape[-1])
        return self.extracted & (self.matched_id == k)

    @staticmethod
    def concatenate(chunks: Sequence[CameraFrames]) -> CameraFrames:
        """Join captures along the frame axis (axis 1)."""
        if len(chunks) == 0:
            raise ValueError("chunks must hold at least one CameraFrames")
        return CameraFrames(
            *(
                np.concatenate([c[i] for c in chunks], axis=1)
                for i in range(len(CameraFrames._fields))
            )
        )


def extraction_rate(frames: CameraFrames) -> float:
    """Extracted / visible landmark observations over all users and frames of ``frames``.

    Raises:
        ValueError: no landmark was visible (the rate is undefined).
    """
    n = int(np.count_nonzero(frames.visible))
    if n == 0:
        raise ValueError("frames.visible holds no visible landmark: extraction_rate is undefined")
    return int(np.count_nonzero(frames.extracted)) / n


def matching_rate(frames: CameraFrames) -> float:
    """Correct matches / extracted features over all users and frames of ``frames``.

    Raises:
        ValueError: no feature was extracted (the rate is undefined).
    """
    n = int(np.count_nonzero(frames.extracted))
    if n == 0:
        raise ValueError("frames.extracted holds no extracted feature: matching_rate is undefined")
    return int(np.count_nonzero(frames.correct)) / n
