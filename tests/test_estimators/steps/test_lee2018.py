"""The Lee-2018-style detector against synthetic headset tracks with known steps."""

import numpy as np
import pytest

from estimators import rotations as rot
from estimators.steps import Lee2018Params, Lee2018Steps

FS = 100.0


def _track(seconds: float, cadence: float, bob_m: float, pitch_deg_amp: float, nod_hz: float):
    """A headset on a neck pivot at 1.55 m: the pivot bobs down ``bob_m`` (peak to peak) once
    per step (its lowest points at the steps), the head nods about the pivot."""
    t = np.arange(int(seconds * FS)) / FS
    pivot_z = 1.55 - 0.5 * bob_m * (1.0 - np.cos(2 * np.pi * cadence * t))
    pitch = np.deg2rad(pitch_deg_amp) * np.sin(2 * np.pi * nod_hz * t)
    ypr = np.stack([np.zeros_like(t), pitch, np.zeros_like(t)], -1)
    q = rot.quat_from_ypr(ypr)
    offset = np.array(Lee2018Params().neck_to_headset_m)
    pos = np.stack([np.zeros_like(t), np.zeros_like(t), pivot_z], -1) + rot.quat_rotate(q, offset)
    steps_at = (np.arange(int(seconds * cadence)) + 0.5) / cadence
    return t, pos[None], q[None], steps_at


def _run(pos, q, params=None, chunk=10):
    det = Lee2018Steps(1, FS, params)
    zeros = np.zeros(pos.shape)
    times = []
    for k in range(0, pos.shape[1], chunk):
        out = det.update(
            zeros[:, k : k + chunk],
            zeros[:, k : k + chunk],
            q[:, k : k + chunk],
            position=pos[:, k : k + chunk],
        )
        times += list(out.peak_time[0][out.steps[0] > 0][:, 0])
    return np.array(times)


def test_each_dip_of_the_pivot_is_one_step_at_its_deepest_point():
    _, pos, q, steps_at = _track(10.0, 1.7, 0.025, 0.0, 0.0)
    found = _run(pos, q)
    expected = steps_at[steps_at > 1.0]  # the baseline settles in the first second
    hits = [np.min(np.abs(found - s)) for s in expected]
    assert max(hits) <= 2.0 / FS
    assert found.size <= steps_at.size


def test_nodding_about_the_pivot_is_not_a_step_and_steps_count_through_it():
    _, pos, q, _ = _track(10.0, 1.7, 0.0, 25.0, 0.8)  # standing, nodding 25 deg
    assert _run(pos, q).size == 0
    _, pos, q, steps_at = _track(10.0, 1.7, 0.025, 25.0, 0.8)  # stepping while nodding
    found = _run(pos, q)
    expected = steps_at[steps_at > 1.0]
    assert all(np.min(np.abs(found - s)) <= 2.0 / FS for s in expected)


def test_the_chunking_does_not_change_the_steps():
    _, pos, q, _ = _track(6.0, 2.0, 0.02, 10.0, 0.5)
    np.testing.assert_array_equal(_run(pos, q, chunk=1), _run(pos, q, chunk=37))


def test_bad_input_is_named():
    det = Lee2018Steps(1, FS)
    z = np.zeros((1, 5, 3))
    q = np.tile([1.0, 0, 0, 0], (1, 5, 1))
    with pytest.raises(ValueError, match="needs position="):
        det.update(z, z, q)
    with pytest.raises(ValueError, match=r"position must have shape \(1, 5, 3\)"):
        det.update(z, z, q, position=np.zeros((1, 4, 3)))
    with pytest.raises(ValueError, match=r"Lee2018Params.dip_m=0.0: must be in \(0, 0.2\] m"):
        Lee2018Params(dip_m=0.0)
