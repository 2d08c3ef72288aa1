"""The estimators of B simulated users, built from an :class:`EstimatorConfig`.

:func:`build_stages` is the one place that builds and checks the user side's estimation: it
resolves each stage of the configuration in its registry (:mod:`estimators.stages`) and builds it
for the batch, and builds the parts every pipeline has beside them: the hand front end (Kinect
frames -> target, smoothed joints, wrist angles), the cadence estimate and, with the
visual-inertial pose source, the head tracker. :class:`SimulatedUsers
<vrloco_env.users.SimulatedUsers>` receives the result and only composes it. A stage that comes
from outside the package (a ``"module:attr"`` string, a class or an object with a ``build`` method
that is not one of ours) is wrapped once in an :class:`estimators.checked.CheckedStage`, which
checks every output against its stage's contract (:class:`estimators.stages.StageContract`, beside
the stage's protocol: shape and meaning: unit quaternions, step times on the stream's clock, hand
angles in range, bounded positions; ``docs/protocols.md``) and names the stage, the plug-in, the
offending value and the rule on a failure. The package's own stages are used as built.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from estimators import stages as st
from estimators.checked import CheckedStage
from estimators.hand import HandPipeline
from estimators.registry import Registry
from estimators.steps import CadenceEstimator
from vrloco_env.batch_rng import BatchRng
from vrloco_env.config import POSE_SOURCES, STAGE_FIELDS, EstimatorConfig, SensorConfig
from vrloco_env.head_tracking import VisualInertialTracker

__all__ = ["Stages", "build_stages"]

_OURS = ("estimators.", "vrloco_env.", "agents.")


@dataclass
class Stages:
    """Every estimator of B users: one built stage per field of
    :data:`~vrloco_env.config.STAGE_FIELDS` and the parts beside them.

    Attributes:
        attitude, steps, hand, steering, locomotion: the stages.
        hand_pipeline: the hand front end (Yao 2023's target selection, joint smoothing and wrist
            angles) whose frames the hand stage filters.
        cadence: the cadence of the detected steps.
        tracker: the head camera + PnP + visual-inertial filter with the visual-inertial pose
            source (it replaces the attitude stage and the locomotion); None walking in place.
        step_length: the locomotion's step length (m): also how far a true step carries the
            virtual body under perfect sensing.
        pose_source: what moves the virtual head (``"walk_in_place"``, or
            ``"visual_inertial"`` with a tracker; :attr:`vrloco_env.config.EnvConfig.pose_source`).
        labels: stage -> the short name of its choice.
        trusted: stage -> whether it is one of the package's own (used as built); the others
            are :class:`~estimators.checked.CheckedStage` proxies of the plug-in.
    """

    attitude: st.AttitudeStage
    steps: st.StepStage
    hand: st.HandStage
    steering: st.SteeringStage
    locomotion: st.Locomotion
    hand_pipeline: HandPipeline
    cadence: CadenceEstimator
    tracker: VisualInertialTracker | None
    step_length: float
    pose_source: str
    labels: dict[str, str]
    trusted: dict[str, bool]


def _is_ours(spec: Any, registry: Registry) -> bool:
    if isinstance(spec, str):
        return spec in registry
    return type(spec).__module__.startswith(_OURS)


def build_stages(
    estimators: EstimatorConfig,
    sensors: SensorConfig,
    batch_size: int,
    pose_source: str = "walk_in_place",
    rng: BatchRng | None = None,
) -> Stages:
    """Build every estimator of ``estimators`` for ``batch_size`` users.

    The attitude and step stages run at the IMU rate (``sensors.imu_rate_hz``), the hand front
    end on the Kinect's frames and the hand stage at their rate, then steering, and locomotion
    with the configuration's step length; beside them the cadence estimate and, with
    ``pose_source="visual_inertial"``, the visual-inertial tracker (``sensors.head_camera``,
    ``estimators.visual_inertial``), whose camera draws its noise from ``rng`` (the users' random
    streams; the camera's construction draws one normal per user). A plug-in that is not one of
    the package's own is returned inside a :class:`~estimators.checked.CheckedStage`.

    Raises:
        ValueError: an unknown ``pose_source``, or the visual-inertial one without ``rng``.
    """
    if pose_source not in POSE_SOURCES:
        raise ValueError(f"pose_source={pose_source!r}: must be one of {POSE_SOURCES}")
    imu_rate_hz = sensors.imu_rate_hz
    args = {
        "attitude": (batch_size, imu_rate_hz),
        "steps": (batch_size, imu_rate_hz),
        "hand": (batch_size, sensors.kinect.frame_rate_hz),
        "steering": (batch_size,),
        "locomotion": (batch_size, estimators.step_length),
    }
    built: dict[str, Any] = {}
    labels: dict[str, str] = {}
    trusted: dict[str, bool] = {}
    for name in STAGE_FIELDS:
        registry: Registry = getattr(st, name.upper())
        spec = getattr(estimators, name)
        stage = registry.build(spec, *args[name])
        labels[name] = registry.label(spec)
        trusted[name] = _is_ours(spec, registry)
        if not trusted[name]:
            rate = args[name][1] if name in ("attitude", "steps", "hand") else None
            stage = CheckedStage(stage, registry, labels[name], batch_size, rate)
        built[name] = stage
    tracker = None
    if pose_source == "visual_inertial":
        if rng is None:
            raise ValueError(
                'pose_source="visual_inertial" needs rng, for the head camera\'s noise'
            )
        tracker = VisualInertialTracker(
            batch_size, imu_rate_hz, sensors.head_camera, estimators.visual_inertial, rng
        )
    return Stages(
        **built,
        hand_pipeline=HandPipeline(batch_size, estimators.hand_pipeline),
        cadence=CadenceEstimator(batch_size),
        tracker=tracker,
        step_length=estimators.step_length,
        pose_source=pose_source,
        labels=labels,
        trusted=trusted,
    )
