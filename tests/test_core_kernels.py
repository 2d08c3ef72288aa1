"""The compiled per-step kernels of the environment against their numpy twins."""

import gymnasium as gym
import numpy as np
import pytest

import vrloco_env  # noqa: F401
from estimators import rotations as rot
from vrloco_env._core_numba import attitude_error_kernel, quat_to_ypr_rows
from vrloco_env.rooms import RoomBatch, RoomConfig
from vrloco_env.tasks import make_layout


@pytest.mark.parametrize("env_id", ["VRLoco-Approach-v0", "VRLoco-Interact-v0"])
def test_observation_kernel_equals_its_uncompiled_reference(env_id, monkeypatch):
    import vrloco_env.core as core_module
    from vrloco_env._core_numba import observation_kernel

    env = gym.make(env_id)
    core = env.unwrapped.core

    def reference(reset_rows=None):
        with monkeypatch.context() as m:
            m.setattr(core_module, "observation_kernel", observation_kernel.py_func)
            return core.observe(reset_rows)[0]

    obs, _ = env.reset(seed=3)
    np.testing.assert_array_equal(obs, reference(np.arange(1)))
    env.action_space.seed(3)
    seen_hand = 0
    for _ in range(200):
        obs, *_, term, trunc, _ = env.step(env.action_space.sample())
        np.testing.assert_array_equal(obs, reference())
        seen_hand += bool(np.isfinite(core.last.hand_est).all())
        if term or trunc:
            obs, _ = env.reset()
            np.testing.assert_array_equal(obs, reference(np.arange(1)))
    assert seen_hand > 50  # the hand entries were exercised, not only their zero default
    env.close()


def test_attitude_error_and_euler_kernels_equal_the_rotation_module():
    rng = np.random.default_rng(0)
    q = rot.quat_normalize(rng.normal(size=(500, 4)))
    ypr = rot.quat_to_ypr(rot.quat_normalize(rng.normal(size=(500, 4))))
    err = np.empty(500)
    attitude_error_kernel(q, ypr, err)
    expect = rot.rotation_angle(rot.quat_multiply(rot.quat_conjugate(q), rot.quat_from_ypr(ypr)))
    np.testing.assert_allclose(err, expect, atol=1e-12)
    # Euler angles, gimbal lock included (pitch +-90 deg).
    q2 = np.concatenate([q, rot.quat_from_ypr([[0.3, np.pi / 2, 0.2], [-1.0, -np.pi / 2, 0.5]])])
    out = np.empty((q2.shape[0], 3))
    quat_to_ypr_rows(q2, out)
    np.testing.assert_allclose(out, rot.quat_to_ypr(q2), atol=1e-9)


def test_ray_fan_equals_ray_cast():
    cfg = RoomConfig()
    rng = np.random.default_rng(1)
    layouts = [make_layout("approach", cfg, rng) for _ in range(4)]
    rooms = RoomBatch(layouts)
    pos = np.array([lay.start[:2] for lay in layouts])
    heading = rng.uniform(-np.pi, np.pi, 4)
    offsets = np.linspace(-1.0, 1.0, 9)
    fan = rooms.ray_fan(pos, heading, offsets, 8.0)
    origins = np.broadcast_to(pos[:, None, :], (4, 9, 2))
    np.testing.assert_array_equal(fan, rooms.ray_cast(origins, heading[:, None] + offsets, 8.0))
    assert (fan < 8.0).any()  # some rays hit something
    with pytest.raises(ValueError, match="finite"):
        rooms.ray_fan(pos, np.full(4, np.nan), offsets, 8.0)


def test_step_summary_kernel_equals_the_numpy_summary():
    from vrloco_env.batch_rng import BatchRng
    from vrloco_env.config import EstimatorConfig, SensorConfig
    from vrloco_env.motion import MotionParams
    from vrloco_env.pipeline import build_stages
    from vrloco_env.users import SimulatedUsers

    b = 6
    stages = build_stages(EstimatorConfig(), b, 100.0, 30.0)
    users = SimulatedUsers(b, BatchRng.from_seeds(range(b)), MotionParams(), SensorConfig(),
                           EstimatorConfig(), stages)  # fmt: skip
    rng = np.random.default_rng(0)
    users._since_step[:] = [np.inf, 0.3, 0.05, 1.0, 0.2, np.inf]
    users.cadence[:] = rng.uniform(0, 3, b)
    users.yaw_offset[:] = rng.uniform(-3, 3, b)
    users.true_yaw_offset[:] = rng.uniform(-3, 3, b)
    for _ in range(20):
        gait_steps = (rng.random((b, 10)) < 0.08).astype(np.int8)
        true_step = rng.random((b, 10)) < 0.08
        yaw_est, yaw_true = rng.uniform(-4, 4, b), rng.uniform(-4, 4, b)
        since, cadence = users._since_step.copy(), users.cadence.copy()
        fast = users._summary(gait_steps, true_step, yaw_est, yaw_true)
        after = users._since_step.copy(), users.cadence.copy()
        users._since_step[:], users.cadence[:] = since, cadence
        ref = users._summary_reference(gait_steps, true_step, yaw_est, yaw_true)
        for a, r in zip(fast, ref, strict=True):
            np.testing.assert_allclose(a, r, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(after[0], users._since_step)
        np.testing.assert_allclose(after[1], users.cadence, rtol=0, atol=1e-12)
    assert users.cadence.max() > 0.5  # steps were detected: the cadence path ran


def test_parallel_builds_give_the_serial_builds_bits(monkeypatch):
    """Vector envs of >= PARALLEL_MIN_BATCH users run the motion and Kinect kernels on all
    cores; the episodes must not change (users share no scratch memory)."""
    from estimators import _parallel

    n = _parallel.PARALLEL_MIN_BATCH

    def run():
        envs = gym.make_vec("VRLoco-Interact-v0", num_envs=n)
        obs, _ = envs.reset(seed=4)
        envs.action_space.seed(4)
        out = [obs]
        for _ in range(12):
            obs, reward, *_ = envs.step(envs.action_space.sample())
            out += [obs, reward]
        envs.close()
        return out

    parallel = run()
    monkeypatch.setattr(_parallel, "PARALLEL_MIN_BATCH", 10**9)  # serial builds only
    serial = run()
    for a, b in zip(parallel, serial, strict=True):
        np.testing.assert_array_equal(a, b)
