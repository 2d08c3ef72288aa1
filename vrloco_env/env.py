"""The single-user Gymnasium environment (``gym.make("vrloco_env:VRLoco-Approach-v0")``).

Spaces:

* action: ``Box(-1, 1, (5,), float32)`` = [walk, turn, hand yaw rate, hand pitch rate, hand roll
  rate] (see :mod:`vrloco_env.actions`: ``walk <= 0`` stands still; finite values outside [-1, 1]
  are clipped to the box, NaN/inf raise a ValueError).
* observation: ``Box(-1, 1, (n,), float32)``, declared by ``env.observation_spec``
  (:mod:`vrloco_env.observation`: entry names, scales, units, and ``decode``): the estimated head
  attitude (virtual heading as sin/cos, pitch, roll), the gait state (walking, steps this step,
  cadence), the estimated hand orientation, the goal bearing and distance and the ray ranges seen
  from the *virtual* pose, then the task's own fields (Interact: the hand error and dwell).

``info`` holds the ground truth and the errors (see :meth:`vrloco_env.core.LocoCore.infos`):
true and estimated head attitude, true and detected steps, true and estimated hand orientation,
``collision``, ``collisions``, ``cost`` (1 for a blocked step, Safety-Gymnasium style),
``distance_to_goal``, ``is_success``, the virtual and true positions.

Copies. ``copy.deepcopy(env)``, ``pickle`` and ``copy.copy(env)`` (a deep copy too: a shallow one
would share the users, rooms and random streams, so that stepping either env moved both) give an
env that goes on exactly as the original, bit for bit, from wherever it is in its episode. The
PyBullet world a render mode builds is not copied: the copy builds its own from the room at its
first render. An env with ``render_mode="human"`` cannot be copied (PyBullet opens one GUI window
per process): a TypeError says so. ``copy.copy`` of ``gym.make``'s wrappers copies the wrappers
only, which then share this env; use ``copy.deepcopy`` for a wrapped env.
"""

from __future__ import annotations

import copy
from dataclasses import replace
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from vrloco_env.actions import ACTION_SIZE, check_action
from vrloco_env.config import (
    DEFAULT_IMU,
    EnvConfig,
    EstimatorConfig,
    RewardConfig,
    SensorConfig,
)
from vrloco_env.core import LocoCore
from vrloco_env.techniques import TECHNIQUES, Technique, get_technique
from vrloco_env.world import RoomConfig

__all__ = ["VRLocoEnv", "make_configs", "technique_name"]

RENDER_SIZE = 480


def make_configs(
    config: EnvConfig | None = None,
    sensors: SensorConfig | None = None,
    estimators: EstimatorConfig | None = None,
    room: RoomConfig | None = None,
    reward: RewardConfig | None = None,
    sensor_preset: str | None = None,
    locomotion: str | None = None,
    max_episode_steps: int | None = None,
    pose_source: str | None = None,
    technique: str | Technique | None = None,
    population: Any = None,
) -> tuple[EnvConfig, SensorConfig, EstimatorConfig, RoomConfig, RewardConfig]:
    """Fill in defaults and apply the technique and the keyword shortcuts, with clear errors for
    wrong types and for arguments that contradict each other (a ``sensor_preset`` other than
    ``sensors.imu`` or the technique's preset, ``estimators`` beside a technique, ...)."""
    for name, value, cls in (
        ("config", config, EnvConfig),
        ("sensors", sensors, SensorConfig),
        ("estimators", estimators, EstimatorConfig),
        ("room", room, RoomConfig),
        ("reward", reward, RewardConfig),
    ):
        if value is not None and not isinstance(value, cls):
            raise TypeError(f"{name} must be a {cls.__name__}, got {type(value).__name__}")
    given_imu = _imu_name(sensors)  # None: the caller's SensorConfig names no IMU
    if technique is not None:
        tech = get_technique(technique)
        if estimators is not None:
            raise ValueError(
                f"estimators=... contradicts technique={tech.name!r}, which sets the estimators; "
                "give one (or register a Technique with your EstimatorConfig)"
            )
        for arg, value in (("sensor_preset", sensor_preset), ("sensors.imu", given_imu)):
            if value not in (None, tech.sensor_preset):
                raise ValueError(
                    f"{arg}={value!r} contradicts technique={tech.name!r} "
                    f"(sensor preset {tech.sensor_preset!r}); give one"
                )
        if locomotion is not None and locomotion != tech.estimators.locomotion:
            raise ValueError(
                f"locomotion={locomotion!r} contradicts technique={tech.name!r} (locomotion "
                f"{tech.estimators.locomotion!r}); give one"
            )
        sensor_preset, estimators = tech.sensor_preset, tech.estimators
    elif sensor_preset is not None and given_imu not in (None, sensor_preset):
        raise ValueError(
            f"sensor_preset={sensor_preset!r} contradicts sensors=SensorConfig(imu="
            f"{given_imu!r}); give one"
        )
    config = config or EnvConfig()
    sensors = sensors or SensorConfig()
    estimators = estimators or EstimatorConfig()
    if sensors.imu is None or sensor_preset is not None:
        sensors = replace(sensors, imu=sensor_preset or DEFAULT_IMU)
    if locomotion is not None:
        estimators = replace(estimators, locomotion=locomotion)
    if max_episode_steps is not None:
        horizon = replace(config, max_episode_steps=max_episode_steps)  # checks the value
        if config.max_episode_steps not in (EnvConfig.max_episode_steps, max_episode_steps):
            raise ValueError(
                f"max_episode_steps={max_episode_steps!r} contradicts config=EnvConfig("
                f"max_episode_steps={config.max_episode_steps}); give one (gym.make_vec gives "
                f"the id's registered max_episode_steps={EnvConfig.max_episode_steps} when you "
                "give none: give the horizon as gym.make_vec(..., max_episode_steps=N))"
            )
        config = horizon
    if pose_source is not None:
        config = replace(config, pose_source=pose_source)
    if population is not None:
        if config.population is not None and config.population != population:
            raise ValueError(
                f"population={population!r} contradicts config.population="
                f"{config.population!r}; give one"
            )
        config = replace(config, population=population)
    return config, sensors, estimators, room or RoomConfig(), reward or RewardConfig()


def _imu_name(sensors: SensorConfig | None) -> str | None:
    """The IMU preset the caller's ``sensors`` names (None: it names none)."""
    if sensors is None or sensors.imu is None:
        return None
    return sensors.preset_name


def technique_name(sensors: SensorConfig, estimators: EstimatorConfig) -> str:
    """The registered technique these sensors and estimators make up, or ``"custom"``."""
    for tech in TECHNIQUES.values():
        if tech.sensor_preset == sensors.preset_name and tech.estimators == estimators:
            return tech.name
    return "custom"


class VRLocoEnv(gym.Env):
    """One simulated VR user walking in place (or, with ``pose_source="visual_inertial"``, really
    walking, tracked by a head camera and IMU) through a virtual room.

    Args:
        task: a registered task (:mod:`vrloco_env.tasks`: ``"approach"``, ``"avoid"``,
            ``"interact"``, or one registered with ``register_task``).
        render_mode: None, ``"rgb_array"`` (top-down map beside a first-person view) or
            ``"human"`` (a PyBullet GUI window; needs a display).
        config, sensors, estimators, room, reward: configuration dataclasses
            (:mod:`vrloco_env.config`, :class:`vrloco_env.world.config.RoomConfig`).
        sensor_preset, locomotion, max_episode_steps, pose_source: shortcuts for common fields
            (``pose_source="visual_inertial"``: :attr:`vrloco_env.config.EnvConfig.pose_source`).
        technique: a registered technique's name (:mod:`vrloco_env.techniques`), a
            ``"module:attr"`` naming a :class:`~vrloco_env.techniques.Technique`, or one: the
            sensor preset and every estimation stage at once.
        task_config: the task's own configuration (e.g.
            :class:`~vrloco_env.tasks.interact.InteractConfig`).
        population: shortcut for :attr:`EnvConfig.population <vrloco_env.config.EnvConfig>`:
            the simulated humans' head behaviour (``"typical"``, ``"gaze_scanners"``,
            ``"nodders"``; :mod:`vrloco_env.user.population`).
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array", "human"], "render_fps": 10}

    def __init__(
        self,
        task: str = "approach",
        render_mode: str | None = None,
        config: EnvConfig | None = None,
        sensors: SensorConfig | None = None,
        estimators: EstimatorConfig | None = None,
        room: RoomConfig | None = None,
        reward: RewardConfig | None = None,
        sensor_preset: str | None = None,
        locomotion: str | None = None,
        max_episode_steps: int | None = None,
        pose_source: str | None = None,
        technique: str | Technique | None = None,
        task_config: Any = None,
        population: Any = None,
    ) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode={render_mode!r}: must be None or one of "
                f"{', '.join(self.metadata['render_modes'])}"
            )
        cfgs = make_configs(
            config,
            sensors,
            estimators,
            room,
            reward,
            sensor_preset,
            locomotion,
            max_episode_steps,
            pose_source,
            technique,
            population,
        )
        self.config, self.sensors, self.estimators, self.room, self.reward = cfgs
        #: the technique's name (``"custom"`` for an unregistered combination)
        self.technique = (
            technique_name(self.sensors, self.estimators)
            if technique is None
            else get_technique(technique).name
        )
        self.task_name = task
        self.render_mode = render_mode
        self.core = LocoCore(task, 1, *cfgs, task_config=task_config)
        #: the observation's fields, scales and units (``observation_spec.decode(obs)``)
        self.observation_spec = self.core.spec
        # The modes this env can render here: "human" only where a display exists, so that
        # gymnasium's checker (which renders every declared mode) passes on a headless machine;
        # asking for "human" without a display still fails with a clear error at reset.
        from vrloco_env.world.sim import display_available

        modes = [m for m in self.metadata["render_modes"] if m != "human" or display_available()]
        self.metadata = {
            **self.metadata,
            "render_modes": modes,
            "render_fps": round(1.0 / self.core.dt),
        }
        self.action_space = spaces.Box(-1.0, 1.0, (ACTION_SIZE,), np.float32)
        self.observation_space = spaces.Box(-1.0, 1.0, (self.core.obs_size,), np.float32)
        self._sim = None
        self._sim_layout = None
        self._path: list[NDArray] = []
        self._true_path: list[NDArray] = []
        self._closed = False

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float32], dict]:
        super().reset(seed=seed)
        self.core.generators[0] = self.np_random
        obs = self.core.reset()
        self._path = [self.core.ep.position[0].copy()]
        self._true_path = [self.core.ep.true_position[0].copy()]
        if self.render_mode == "human":
            self._sync_sim()
        info = {
            "distance_to_goal": float(self.core.ep.distance[0]),
            "shortest_path": float(self.core.ep.shortest[0]),
            "is_success": False,
            "collisions": 0,
            "position": self.core.ep.position[0].copy(),
            "step_report_delay_s": self.core.step_report_delay_s,
        }
        return obs[0], info

    def step(self, action: Any) -> tuple[NDArray[np.float32], float, bool, bool, dict]:
        a = check_action(action)
        obs, reward, terminated, truncated, infos = self.core.step(a[None])
        self._path.append(self.core.ep.position[0].copy())
        self._true_path.append(self.core.ep.true_position[0].copy())
        # Every value keeps one shape for the whole episode (step times stay padded), so
        # that gymnasium's sync and async vector envs can stack the infos of their sub-envs.
        info = {k: (v[0] if v.ndim > 1 else v[0].item()) for k, v in infos.items()}
        if self.render_mode == "human":
            self._sync_sim()
        return obs[0], float(reward[0]), bool(terminated[0]), bool(truncated[0]), info

    # ------------------------------------------------------------------------------ rendering
    @property
    def layout(self):
        """The current room (local frame)."""
        return self.core.layouts[0]

    def render(self) -> NDArray[np.uint8] | None:
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode=... to make")
            return None
        if self.core.rooms is None:
            raise RuntimeError("reset() must be called before render()")
        if self.render_mode == "human":
            self._sync_sim()
            return None
        from vrloco_env.world.render import draw_map

        last = self.core.last
        hand = None if last is None else last.hand_est[0]
        top = draw_map(
            self.layout,
            self.core.ep.position[0],
            float(self.core.ep.virtual_yaw[0]),
            np.array(self._path),
            np.array(self._true_path),
            self.core.last_rays[0],
            self.core.ray_offsets,
            hand,
            RENDER_SIZE,
        )
        return np.concatenate([top, self._first_person()], axis=1)

    def _sync_sim(self) -> None:
        """Build the current room in PyBullet (once per layout) and place the avatar."""
        from vrloco_env.world import build
        from vrloco_env.world.sim import Simulation

        if self._sim is None:
            self._sim = Simulation(render_mode=self.render_mode)
        layout = self.layout
        if self._sim_layout is not layout:
            self._sim.clear()
            self._ids = build(self._sim, layout)
            self._sim_layout = layout
        p = self.core.ep.position[0]
        yaw = float(self.core.ep.virtual_yaw[0])
        self._sim.set_poses([self._ids["avatar"]], [[p[0], p[1], layout.avatar_height / 2]], [yaw])
        if self.render_mode == "human":
            self._sim.place_gui_camera(
                (p[0], p[1], 1.0),
                distance=4.0,
                yaw_deg=float(np.rad2deg(yaw)) - 90.0,
                pitch_deg=-35.0,
            )

    def _first_person(self) -> NDArray[np.uint8]:
        self._sync_sim()
        assert self._sim is not None
        p = self.core.ep.position[0]
        yaw = float(self.core.ep.virtual_yaw[0])
        pitch = 0.0 if self.core.last is None else float(self.core.last.ypr_est[0, 1])
        eye = np.array([p[0], p[1], 1.6]) + 0.3 * np.array([np.cos(yaw), np.sin(yaw), 0.0])
        look = np.array([np.cos(yaw) * np.cos(pitch), np.sin(yaw) * np.cos(pitch), -np.sin(pitch)])
        return self._sim.camera_image(
            eye, eye + look, width=RENDER_SIZE, height=RENDER_SIZE, fov_deg=90.0
        )

    def close(self) -> None:
        if self._sim is not None:
            self._sim.close()
            self._sim = None
        self._closed = True

    # ------------------------------------------------------------------------------ copies
    def __getstate__(self) -> dict[str, Any]:
        """The env's state for ``copy.deepcopy`` and ``pickle``, without its PyBullet world
        (a connection to a physics server; the copy builds its own from the room when it first
        renders).

        Raises:
            TypeError: with ``render_mode="human"`` (one PyBullet GUI window per process).
        """
        if self.render_mode == "human":
            raise TypeError(
                "a VRLocoEnv with render_mode='human' cannot be copied or pickled: its PyBullet "
                "GUI window cannot be duplicated (PyBullet opens one per process); copy an env "
                "made with render_mode=None or 'rgb_array'"
            )
        state = self.__dict__.copy()
        state["_sim"] = state["_sim_layout"] = None
        state.pop("_ids", None)
        return state

    def __copy__(self) -> VRLocoEnv:
        """A deep copy (:func:`copy.deepcopy`): a shallow one would share the users, the rooms
        and the random streams with this env, so that stepping either moved both."""
        return copy.deepcopy(self)
