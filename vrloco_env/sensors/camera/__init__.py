"""Head camera model for the helmet-tracking paper's visual helmet pose: wall landmarks seen by a
pinhole camera.

A camera on the helmet looks at landmarks with known 3-D positions on the room's inner walls
(:attr:`vrloco_env.world.layout.Layout.landmarks`). For B users and N frames at once,
:class:`HeadCamera` projects every landmark, decides which ones are geometrically visible, which of
those a feature detector extracts, which extracted features a matcher assigns to the right landmark,
and adds pixel noise. The output (:class:`CameraFrames`) is what a PnP solver (OpenCV
``solvePnPRansac``) takes: 2-D pixels with the landmark index the matcher assigned, outliers
included.

Frames and conventions
----------------------
*World*: ENU, z up (:mod:`estimators.rotations`). *Head body frame*: x forward, y left, z up;
``quat`` rotates body -> world. *Camera frame*: OpenCV's, x right, y down, z forward (optical
axis). Without a mount tilt the camera axes are camera z = body x, camera x = -body y, camera
y = -body z (:data:`BODY_FROM_CAMERA`). The mount (:attr:`CameraSpec.mount_offset_m`, body frame, m;
:attr:`CameraSpec.mount_tilt_deg`, positive tilts the optical axis down, a rotation about body +y)
places the camera on the helmet; :func:`camera_pose` gives the camera's world pose, and
:func:`head_pose_from_camera` turns a camera pose (e.g. from PnP) back into a head pose.

Pinhole model, no lens distortion (the images are taken as rectified; decision, the helmet-tracking
paper gives only fx, fy, cx, cy): ``u = fx X / Z + cx``, ``v = fy Y / Z + cy`` for a camera-frame
point ``(X, Y, Z)``, pixel centres at integer coordinates (OpenCV), so the image spans
``[-0.5, width - 0.5] x [-0.5, height - 0.5]`` px. The defaults (640 x 480 px, fx = fy = 460 px,
principal point at the image centre) give a 69.6 deg x 55.1 deg field of view, a typical helmet
tracking camera. :attr:`CameraSpec.camera_matrix` is OpenCV's K; ``fx, fy, cx, cy, width,
height`` are plain fields, so ``estimators.head_pose.pnp.CameraIntrinsics(spec.fx, spec.fy,
spec.cx, spec.cy, spec.width, spec.height)`` describes the same camera.

Per landmark and frame (all decisions, the helmet-tracking paper states only the outcome rates)
-------------------------------------------------------------------------------
1. *Visible* (geometry): in front of the camera with depth ``Z >= min_range_m``, distance from the
   camera ``<= max_range_m``, projection inside the image, not flagged ``blocked`` by the caller
   (e.g. an obstacle in the line of sight, which this model does not ray-cast), and — where wall
   normals are given — seen from the room side of its wall at less than ``max_view_angle_deg``
   from the wall normal (a marker seen edge-on is not detectable; 80 deg by default). Without
   normals the last test is skipped: a head inside the room sees every wall face from its front.
2. *Occluded*: the ``occlusion`` condition puts an occluder in the image — a vertical band of
   ``occluder_fraction`` of the image width (a person, a door frame, a hand in front of the lens)
   whose centre drifts as a random walk of ``occluder_drift_px_per_sqrt_s`` px/sqrt(s), folded
   back at the image borders so that the band always lies fully inside the image. Visible
   landmarks under it are not extracted.
3. *Blur*: the image of a landmark moves, during the exposure, with the rotational optical flow
   ``u' = fx (x y wx - (1 + x^2) wy + y wz)``, ``v' = fy ((1 + y^2) wx - x y wy - x wz)``
   (``x, y`` normalised image coordinates, ``w`` the angular rate in the camera frame); the blur
   length is ``L = |(u', v')| * exposure_s`` px. This is ``|w_perp| * exposure * f`` at the image
   centre, and adds the roll-induced streak off centre. Translation is neglected (at 1.5 m/s and
   2 m it is 0.75 rad/s-equivalent at most, usually far less than head rotation). The frame time
   is the middle of the exposure, so the streak's centroid is the true projection (no bias).
4. *Extracted* (detection): with probability
   ``extraction_prob * exp(-max(L - blur_free_px, 0) / blur_scale_px)`` for a visible,
   unoccluded landmark: a detector tolerates ``blur_free_px`` of smear, then loses corners
   exponentially (engineering choice). Over a room's landmarks, turning about the vertical, the
   motion_blur preset then extracts ~71 % at 1 rad/s and ~24 % at 3 rad/s, the ideal one ~83 %
   at 3 rad/s (95 % when still).
5. *Pixel noise*: independent Gaussian per axis with std
   ``sqrt(pixel_noise_px^2 + (blur_noise_per_px * L)^2)``: the corner localisation error plus the
   centroid uncertainty of a streak (a uniform streak of length L has std L / sqrt(12), the
   default factor). A noisy pixel may fall up to a few px outside the image; it is kept.
6. *Matched*: an extracted feature is given its own landmark index with probability ``match_prob``;
   otherwise (a wrong match) the index of one of its ``match_neighbors`` nearest other landmarks
   (3-D distance; on the wall grid these are the markers next to it, the ones whose descriptors a
   real matcher confuses), chosen uniformly. The pixel stays where the true landmark projects.
   Where a landmark has no other valid landmark, the match cannot go wrong.

Conditions (:data:`LIGHTING`, :func:`camera_spec`), calibrated to the helmet-tracking paper's
rates for a still head (motion lowers extraction further through blur):

===========  ========== ======== ======= =========== ==================================
condition    extraction matching  noise   exposure    other
===========  ========== ======== ======= =========== ==================================
ideal        0.95       0.90     0.5 px  2 ms
low_light    0.70       0.85     1.5 px  4 ms        dim, noisy corners, longer exposure
occlusion    0.95       0.60     0.5 px  2 ms        band over 30 % of the width
motion_blur  0.95       0.90     0.5 px  8.3 ms      full frame-time exposure
===========  ========== ======== ======= =========== ==================================

The helmet-tracking paper reports extraction 95 % ideal / ~70 % low light and matching 90 % / ~60 %
with occlusion. Matching in low light is not reported: 0.85 (engineering choice, dim descriptors are
a little less distinctive). Under occlusion, :func:`extraction_rate` (extracted / visible) is about
``0.95 * (1 - 0.3)``, about 0.67, since the occluder hides visible landmarks; among the unoccluded
ones it stays 0.95. :func:`matching_rate` equals ``match_prob`` in expectation, whatever the
geometry. 0.5 px is the usual sub-pixel corner accuracy; 1.5 px in low light (gain noise). The
exposure of the motion_blur preset is the whole 1/120 s frame time, the longest a 120 Hz camera
allows (a fixed long exposure, or an auto-exposure opening up indoors); low light lengthens the
exposure to 4 ms, so it blurs more than ideal when the head turns.

The extraction and matching probabilities are therefore the model's inputs, set to the paper's
rates, not results. The pixel noise is not the paper's: with it and the ~17 landmarks a frame of
the default room extracts, PnP is about 3x more accurate than the helmet-tracking paper's +-0.05 m /
+-1 deg. The helmet-tracking paper's experiment (:mod:`agents.experiments.vio`) scales every
preset's noise by a factor calibrated to the paper's visual-only error; the presets here (and the
env's camera) keep the sub-pixel corner accuracy.

Randomness
----------
Every number comes from the :class:`~vrloco_env.batch_rng.BatchRng` passed in. :meth:`HeadCamera.
reset` draws one normal per reset user (the occluder's start); :meth:`HeadCamera.capture` draws a
fixed block of ``1 + 3 * max_landmarks`` normals per frame and user (occluder step, then per
landmark slot: one uniform for detection and matching — given a detection ``u < p``, ``u / p`` is
again uniform and decides the match —, pixel noise u, pixel noise v), whatever K the landmark array
has. So a batch of B users equals B single runs bit for bit — also when a single run passes only
its own landmarks and the batch pads them (padding at the end) — and a capture split into chunks
equals one capture. The draws are about a third of the cost (a capture of 4 frames for 64 users
and 96 landmarks takes ~4 ms on one core, numpy throughout); the default 128 slots hold the
default rooms' 96-102 landmarks, a larger room needs a larger ``max_landmarks``. Uniforms are the
normal CDF of the draws, as in ``BatchRng.uniform``.

Modules: :mod:`~vrloco_env.sensors.camera.spec` (the specification and lighting presets),
:mod:`~vrloco_env.sensors.camera.geometry` (the camera's pose and projection),
:mod:`~vrloco_env.sensors.camera.landmarks` (the walls' landmarks),
:mod:`~vrloco_env.sensors.camera.frames` (what it delivers) and
:mod:`~vrloco_env.sensors.camera.model` (the camera :class:`HeadCamera`).
"""

from estimators.registry import renamed_attributes
from vrloco_env.sensors.camera.frames import CameraFrames, extraction_rate, matching_rate
from vrloco_env.sensors.camera.geometry import camera_pose, head_pose_from_camera, project
from vrloco_env.sensors.camera.landmarks import layout_landmarks, pad_landmarks
from vrloco_env.sensors.camera.model import HeadCamera
from vrloco_env.sensors.camera.spec import (
    BODY_FROM_CAMERA,
    LIGHTING,
    MAX_RATE_HZ,
    CameraSpec,
    camera_spec,
)

__all__ = [
    "BODY_FROM_CAMERA",
    "LIGHTING",
    "MAX_RATE_HZ",
    "CameraFrames",
    "CameraSpec",
    "HeadCamera",
    "camera_pose",
    "camera_spec",
    "extraction_rate",
    "head_pose_from_camera",
    "layout_landmarks",
    "matching_rate",
    "pad_landmarks",
    "project",
]

#: ``CONDITIONS``, the old name of :data:`LIGHTING`, still imports (with a warning).
__getattr__ = renamed_attributes(globals(), {"CONDITIONS": "LIGHTING"})
