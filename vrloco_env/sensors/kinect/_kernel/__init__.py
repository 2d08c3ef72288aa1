"""Compiled frame loop of the Kinect v2 model (see :mod:`vrloco_env.sensors.kinect`).

:meth:`vrloco_env.sensors.kinect.KinectV2.capture` validates its input, draws one block of
standard normals per frame from the users' :class:`~vrloco_env.batch_rng.BatchRng` and hands
everything to :func:`capture_frames`, which runs the whole model in one call, per user and frame
in stages: the bystanders (:func:`_bystanders`), camera transform and field of view
(:func:`_camera_space`), each body's facing relative to the sensor (:func:`_facing`), occlusion
(:func:`_occlusion`), tracking and ids (:func:`_track`), jitter
bursts and random inferred episodes (:func:`_episodes`), the noise states
(:func:`_noise_states`), and each body's slot with its noisy joints and wrist orientation
(:func:`_body_out`).

The kernel is plain Python on scalars and small arrays; ``capture_frames.py_func`` runs the same
code uncompiled (``tests/kernel_cases/kinect.py`` checks that both give the same frames). Its
quaternion products are the scalar helpers of :mod:`estimators.kernels.rotations`. Parameters
are named: the spec's fields and derived values in a parameter record, the sensor's pose and the
per-joint tables in :data:`GEOMETRY_FIELDS`, each user's session in :data:`STATE_FIELDS`.

Draw layout
-----------
Each frame of each user consumes ``draw_size(n_bodies)`` normals, in this order (offsets ``Z_*``,
``B_*``, ``Y_*``):

* the target: 75 innovations of its per-joint noise process (joint-major, x y z), 15 normals for
  the extra white noise of a jitter burst (up to 5 limb joints x 3; unused outside bursts), then
  its wrist rotation noise: white (3) and AR(1) innovations (3);
* per body (target first, then the bystanders), ``BODY_DRAWS`` = 3 numbers: the jitter burst
  (start, limb and length from one number), the id the body gets if it is acquired in this frame,
  and the random inferred episodes (starts and lengths from one number);
* per bystander, ``BYSTANDER_DRAWS`` = 10 numbers: its noise vectors, white (3) and AR(1)
  innovations (3), then walk start, distance, lateral offset and speed.

That is 125 numbers per frame for the default two bystanders. Four devices keep the statistics
of the spec while drawing few numbers:

* Rare events test their normal against a threshold, ``z < ndtri(p)`` being ``ndtr(z) < p``; where
  a value is needed the uniform is ``ndtr(z)`` (computed here with ``erfc``).
* Several decisions come from one uniform by *splitting* (:func:`bernoulli_split`,
  :func:`categorical_split`, :func:`geometric_split`): given the outcome of an inverse-CDF draw,
  the uniform's position inside the outcome's interval is again uniform and independent of the
  outcome, so it is rescaled and used for the next decision (exact in real arithmetic; a decision
  of probability P costs log2(1/P) of the double's 53 bits).
* The target's joint noise, white (variance fraction ``wf``) plus unit AR(1) (coefficient ``rho``),
  is the Gaussian process with autocorrelation 1 at lag 0 and ``(1 - wf) rho^k`` at lag k >= 1.
  An AR(1) process plus white noise is an ARMA(1, 1) process (Granger & Morris 1976, "Time series
  modelling and interpretation", J. R. Statist. Soc. A 139(2)), so it is generated from one
  innovation per coordinate and frame in its innovations form
  ``y_t = rho y_{t-1} + s (e_t + theta e_{t-1})`` (:func:`arma_parameters`), not two: the same
  process, half the numbers.
* A bystander's noise is drawn at lower dimension: one white and one AR(1) innovation vector per
  frame drive all its joints (each scaled by its own std, so every joint keeps the spec's std,
  white fraction and time constant, but the skeleton jitters rigidly) and its wrist rotation (its
  own AR(1) state, time constant ``hand_rot_tau_s``). Bystanders matter by where they stand, hide
  the user and get tracked, not by the shape of their jitter; the target keeps independent noise
  per joint and per wrist axis.

Modules, in the order of a frame:

* :mod:`~vrloco_env.sensors.kinect._kernel.layout` — the joints named, the table sizes, the
  records' fields (:data:`GEOMETRY_FIELDS`, :data:`STATE_FIELDS`) and the draw layout
  (:func:`draw_size`);
* :mod:`~vrloco_env.sensors.kinect._kernel.draws` — a normal's uniform and the splitting of one
  uniform (:func:`uniform`, :func:`bernoulli_split`, :func:`categorical_split`,
  :func:`geometric_split`), the ARMA(1, 1) form of the joint noise (:func:`arma_parameters`);
* :mod:`~vrloco_env.sensors.kinect._kernel.scene` — stages 1 to 4: the bystanders, camera space,
  facing, occlusion;
* :mod:`~vrloco_env.sensors.kinect._kernel.tracking` — stage 5: tracking and ids
  (:data:`unique_ids`: the ids of a reset);
* :mod:`~vrloco_env.sensors.kinect._kernel.noise` — stages 6 to 8: the episodes, the noise states,
  each body's slot;
* :mod:`~vrloco_env.sensors.kinect._kernel.capture` — the frame loop (:data:`capture_frames`).
"""

from vrloco_env.sensors.kinect._kernel.capture import capture_frames
from vrloco_env.sensors.kinect._kernel.draws import (
    arma_parameters,
    bernoulli_split,
    categorical_split,
    geometric_split,
    uniform,
)
from vrloco_env.sensors.kinect._kernel.layout import (
    B_BURST,
    B_INFERRED,
    B_NEW_ID,
    BODY_DRAWS,
    BYSTANDER_DRAWS,
    GEOMETRY_FIELDS,
    HIP_LEFT,
    HIP_RIGHT,
    MAX_BODIES,
    MAX_LIMB_JOINTS,
    N_LIMB_GROUPS,
    N_TORSO_JOINTS,
    SHOULDER_LEFT,
    SHOULDER_RIGHT,
    STATE_FIELDS,
    WRIST_RIGHT,
    Y_AR,
    Y_WALK_DIST,
    Y_WALK_LATERAL,
    Y_WALK_SPEED,
    Y_WALK_START,
    Y_WHITE,
    Z_BODIES,
    Z_BURST,
    Z_HAND_AR,
    Z_HAND_WHITE,
    Z_JOINT,
    bystander_offset,
    draw_size,
)
from vrloco_env.sensors.kinect._kernel.tracking import unique_ids

__all__ = [
    "BODY_DRAWS",
    "BYSTANDER_DRAWS",
    "B_BURST",
    "B_INFERRED",
    "B_NEW_ID",
    "GEOMETRY_FIELDS",
    "HIP_LEFT",
    "HIP_RIGHT",
    "MAX_BODIES",
    "MAX_LIMB_JOINTS",
    "N_LIMB_GROUPS",
    "N_TORSO_JOINTS",
    "SHOULDER_LEFT",
    "SHOULDER_RIGHT",
    "STATE_FIELDS",
    "WRIST_RIGHT",
    "Y_AR",
    "Y_WALK_DIST",
    "Y_WALK_LATERAL",
    "Y_WALK_SPEED",
    "Y_WALK_START",
    "Y_WHITE",
    "Z_BODIES",
    "Z_BURST",
    "Z_HAND_AR",
    "Z_HAND_WHITE",
    "Z_JOINT",
    "arma_parameters",
    "bernoulli_split",
    "bystander_offset",
    "capture_frames",
    "categorical_split",
    "draw_size",
    "geometric_split",
    "uniform",
    "unique_ids",
]
