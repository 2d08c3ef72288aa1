"""The compiled per-step kernels of the environment against the rotation module and closed
forms (their compiled-vs-source case is ``kernel_cases/core.py``)."""

import gymnasium as gym
import numpy as np
import pytest
from kernel_cases.core import STEPS, episode

import vrloco_env  # noqa: F401
from estimators import rotations as rot
from vrloco_env._core_numba import attitude_error_kernel, quat_to_ypr_rows
from vrloco_env.tasks import make_layout
from vrloco_env.world import RoomBatch, RoomConfig


def test_the_observation_case_exercises_fresh_users_and_hand_entries():
    """The compiled-vs-source case of the observation kernel (``kernel_cases/core.py``) has
    fresh users (zero attitude and hand entries), users with a hand estimate and one without."""
    obs, errors, hands = episode()
    env = gym.make("VRLoco-Interact-v0")
    spec = env.unwrapped.core.spec
    env.close()
    valid = obs[:, :, spec.slice("hand_valid")][..., 0]
    assert (valid[0] == 0.0).all() and hands.any()
    assert valid[STEPS // 2 + 2, 0] == 0.0 and valid[STEPS // 2 + 2, 1] == 1.0  # user 0 reset
    np.testing.assert_array_equal(valid[-1], [1.0, 0.0])  # user 1's hand estimate is missing
    assert (obs[-1, 1, spec.slice("hand")] == 0.0).all()
    assert np.isfinite(errors).all() and (errors >= 0.0).all()


def test_attitude_error_and_euler_kernels_equal_the_rotation_module():
    rng = np.random.default_rng(0)
    q = rot.quat_normalize(rng.normal(size=(500, 4)))
    ypr = rot.quat_to_ypr(rot.quat_normalize(rng.normal(size=(500, 4))))
    err = np.empty(500)
    attitude_error_kernel(500)(q, ypr, err)
    expect = rot.rotation_angle(rot.quat_multiply(rot.quat_conjugate(q), rot.quat_from_ypr(ypr)))
    np.testing.assert_allclose(err, expect, atol=1e-12)
    # Euler angles, gimbal lock included (pitch +-90 deg).
    q2 = np.concatenate([q, rot.quat_from_ypr([[0.3, np.pi / 2, 0.2], [-1.0, -np.pi / 2, 0.5]])])
    out = np.empty((q2.shape[0], 3))
    quat_to_ypr_rows(q2.shape[0])(q2, out)
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


def test_step_summary_counts_steps_and_turns_the_yaws_into_virtual_ones():
    from estimators.kernels import param_record
    from vrloco_env._core_numba import step_summary_kernel

    b = 6
    rng = np.random.default_rng(0)
    for in_place in (True, False):
        gait_steps = (rng.random((b, 10)) < 0.08).astype(np.int8)
        true_step = rng.random((b, 10)) < 0.08
        yaw_est, off_est, yaw_true, off_true = rng.uniform(-4, 4, (4, b))
        out = (np.empty(b), np.empty(b), np.empty(b), np.empty(b), np.zeros((b, 2)))
        prm = param_record(step_length=0.7, in_place=float(in_place))
        step_summary_kernel(b)(
            gait_steps, true_step, (yaw_est, yaw_true), (off_est, off_true), prm, out
        )
        steps, true_steps, virtual_yaw, true_virtual_yaw, displacement = out
        np.testing.assert_array_equal(steps, gait_steps.sum(axis=1))
        np.testing.assert_array_equal(true_steps, true_step.sum(axis=1))
        np.testing.assert_allclose(virtual_yaw, rot.wrap_angle(yaw_est + off_est), atol=1e-12)
        np.testing.assert_allclose(
            true_virtual_yaw, rot.wrap_angle(yaw_true + off_true), atol=1e-12
        )
        expect = (
            0.7
            * true_steps[:, None]
            * np.stack([np.cos(true_virtual_yaw), np.sin(true_virtual_yaw)], -1)
        )
        np.testing.assert_allclose(displacement, expect if in_place else 0.0, atol=1e-12)


def test_cadence_is_the_step_rate_and_decays_at_rest():
    from estimators.steps import CadenceEstimator

    est = CadenceEstimator(2)
    dt = 0.1
    for k in range(40):  # user 0 steps every 0.5 s (2 steps/s), user 1 stands
        c = est.update(np.array([1.0 if k % 5 == 0 else 0.0, 0.0]), dt)
        if k % 5 == 0 and k > 0:
            assert c[0] == pytest.approx(2.0)
    assert c[1] == 0.0
    for _ in range(15):  # the last step came at k = 35: 4 + 15 updates without one
        c = est.update(np.zeros(2), dt)
    assert c[0] == pytest.approx(2.0 * np.exp(-19 * dt / 1.5), rel=1e-9)
    est = CadenceEstimator(2)
    est.update(np.array([1.0, 0.0]), dt)  # user 0's first step: no interval, no rate
    for _ in range(3):
        est.update(np.zeros(2), dt)
    c = est.update(np.array([2.0, 1.0]), dt)
    assert c[0] == 4.0  # 2 steps in 0.4 s: 5 steps/s, capped at 4
    assert c[1] == 0.0  # a bout's first step: no interval, no rate
    np.testing.assert_array_equal(est.since_step, [0.0, 0.0])


def test_one_thread_keeps_every_batch_on_the_serial_build(monkeypatch):
    """``use_threads(1)`` (a worker with one core of its own) takes the serial build however
    large the batch; a thread count out of range is refused by name."""
    from estimators.kernels import batch
    from vrloco_env.user._motion_numba import evaluate_kernel

    n = batch.PARALLEL_MIN_BATCH
    assert evaluate_kernel(n) is evaluate_kernel.parallel
    assert evaluate_kernel.parallel is not evaluate_kernel.serial
    monkeypatch.setattr(batch, "_serial_only", False)  # restored after the test
    batch.use_threads(1)
    assert evaluate_kernel(n) is evaluate_kernel.serial
    assert evaluate_kernel(10 * n) is evaluate_kernel.serial
    for bad in (0, -1, 1.0, True, batch.numba.config.NUMBA_NUM_THREADS + 1):
        with pytest.raises(ValueError, match=r"n must be an integer in \[1, "):
            batch.use_threads(bad)


@pytest.mark.slow
def test_parallel_builds_give_the_serial_builds_bits(monkeypatch):
    """Vector envs of >= PARALLEL_MIN_BATCH users run the motion and Kinect kernels on all
    cores; the episodes must not change (users share no scratch memory)."""
    from estimators.kernels import batch as _parallel

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
