"""The rotation module against scipy.spatial.transform.Rotation on random batches."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from estimators import rotations as rot

TOL = 1e-12


def random_quats(rng, n):
    return rot.quat_canonical(Rotation.random(n, random_state=rng).as_quat(scalar_first=True))


def test_product_matches_scipy(rng):
    p, q = random_quats(rng, 500), random_quats(rng, 500)
    ours = rot.quat_canonical(rot.quat_multiply(p, q))
    ref = Rotation.from_quat(p, scalar_first=True) * Rotation.from_quat(q, scalar_first=True)
    np.testing.assert_allclose(ours, rot.quat_canonical(ref.as_quat(scalar_first=True)), atol=TOL)


def test_rotate_and_inverse_match_scipy(rng):
    q = random_quats(rng, 500)
    v = rng.normal(size=(500, 3))
    r = Rotation.from_quat(q, scalar_first=True)
    np.testing.assert_allclose(rot.quat_rotate(q, v), r.apply(v), atol=TOL)
    np.testing.assert_allclose(rot.quat_rotate_inverse(q, v), r.inv().apply(v), atol=TOL)
    np.testing.assert_allclose(
        rot.quat_multiply(rot.quat_conjugate(q), q), rot.quat_identity((500,)), atol=TOL
    )


def test_matrix_round_trip_matches_scipy(rng):
    q = random_quats(rng, 500)
    m = rot.quat_to_matrix(q)
    np.testing.assert_allclose(m, Rotation.from_quat(q, scalar_first=True).as_matrix(), atol=TOL)
    np.testing.assert_allclose(rot.matrix_to_quat(m), q, atol=TOL)
    # Every branch of the matrix -> quaternion conversion: rotations of pi about each axis.
    for axis in np.eye(3):
        r = Rotation.from_rotvec(np.pi * axis)
        ref = rot.quat_canonical(r.as_quat(scalar_first=True))
        got = rot.matrix_to_quat(r.as_matrix())
        assert min(np.abs(got - ref).max(), np.abs(got + ref).max()) < TOL


def test_rotvec_exp_log_match_scipy(rng):
    r = rng.normal(size=(500, 3))
    r *= (rng.uniform(0, np.pi, 500) / np.linalg.norm(r, axis=1))[:, None]
    q = rot.quat_from_rotvec(r)
    ref = Rotation.from_rotvec(r).as_quat(scalar_first=True)
    np.testing.assert_allclose(rot.quat_canonical(q), rot.quat_canonical(ref), atol=TOL)
    np.testing.assert_allclose(rot.quat_to_rotvec(q), r, atol=1e-11)
    tiny = np.array([[1e-10, -2e-10, 3e-11], [0.0, 0.0, 0.0]])
    np.testing.assert_allclose(rot.quat_to_rotvec(rot.quat_from_rotvec(tiny)), tiny, atol=1e-20)


def test_euler_zyx_matches_scipy(rng):
    q = random_quats(rng, 500)
    ypr = rot.quat_to_ypr(q)
    np.testing.assert_allclose(
        ypr, Rotation.from_quat(q, scalar_first=True).as_euler("ZYX"), atol=1e-10
    )
    np.testing.assert_allclose(rot.quat_canonical(rot.quat_from_ypr(ypr)), q, atol=TOL)
    np.testing.assert_allclose(
        rot.quat_canonical(rot.quat_from_ypr(ypr)),
        rot.quat_canonical(Rotation.from_euler("ZYX", ypr).as_quat(scalar_first=True)),
        atol=TOL,
    )


def test_euler_gimbal_lock_is_finite_and_consistent():
    ypr = np.array([[0.7, np.pi / 2, 0.0], [-1.2, -np.pi / 2, 0.0]])
    back = rot.quat_to_ypr(rot.quat_from_ypr(ypr))
    np.testing.assert_allclose(back, ypr, atol=1e-7)


def test_frame_convention_enu():
    """Yaw 90 deg turns the body's forward axis (+x) to north (+y); positive pitch tilts it down."""
    q = rot.quat_from_ypr([np.pi / 2, 0.0, 0.0])
    np.testing.assert_allclose(rot.quat_rotate(q, [1.0, 0, 0]), [0, 1.0, 0], atol=TOL)
    q = rot.quat_from_ypr([0.0, np.deg2rad(30), 0.0])
    assert rot.quat_rotate(q, [1.0, 0, 0])[2] < 0


def test_batch_broadcasting(rng):
    q = random_quats(rng, 12).reshape(3, 4, 4)
    v = rng.normal(size=(3, 4, 3))
    out = rot.quat_rotate(q, v)
    assert out.shape == (3, 4, 3)
    np.testing.assert_allclose(out[1, 2], rot.quat_rotate(q[1, 2], v[1, 2]), atol=TOL)
    assert rot.quat_multiply(q, q[0, 0]).shape == (3, 4, 4)


def test_integrate_constant_rate(rng):
    w = rng.normal(size=(8, 3))
    q = rot.quat_identity((8,))
    for _ in range(100):
        q = rot.quat_integrate(q, w, 0.01)
    np.testing.assert_allclose(
        rot.quat_canonical(q), rot.quat_canonical(rot.quat_from_rotvec(w)), atol=1e-12
    )


def test_wrap_and_rotation_angle(rng):
    a = rng.uniform(-20, 20, 1000)
    w = rot.wrap_angle(a)
    assert np.all((w > -np.pi) & (w <= np.pi))
    np.testing.assert_allclose(np.cos(w), np.cos(a), atol=1e-12)
    assert rot.wrap_angle(np.pi) == pytest.approx(np.pi)
    assert rot.angle_diff(np.deg2rad(179), np.deg2rad(-179)) == pytest.approx(np.deg2rad(-2))
    r = rng.normal(size=(100, 3))
    r *= (rng.uniform(0, np.pi, 100) / np.linalg.norm(r, axis=1))[:, None]
    np.testing.assert_allclose(
        rot.rotation_angle(rot.quat_from_rotvec(r)), np.linalg.norm(r, axis=1), atol=1e-12
    )


def test_skew_is_cross_product(rng):
    a, b = rng.normal(size=(2, 50, 3))
    np.testing.assert_allclose(np.einsum("nij,nj->ni", rot.skew(a), b), np.cross(a, b), atol=TOL)


@pytest.mark.parametrize("bad", [[0.0, 0, 0, 0], [np.nan, 0, 0, 1], [1.0, 0, 0]])
def test_ensure_quaternion_rejects_bad_input(bad):
    with pytest.raises(ValueError, match="q"):
        rot.ensure_quaternion(bad)


def test_compiled_scalar_helpers_match_the_numpy_module(rng):
    from estimators.kernels import rotations as nb

    q = random_quats(rng, 50)
    p = random_quats(rng, 50)
    v = rng.normal(size=(50, 3))
    ypr = rot.quat_to_ypr(q)
    for i in range(50):
        np.testing.assert_allclose(nb.quat_from_ypr(*ypr[i]), rot.quat_from_ypr(ypr[i]), atol=TOL)
        np.testing.assert_allclose(
            nb.quat_mul(*p[i], *q[i]), rot.quat_multiply(p[i], q[i]), atol=TOL
        )
        np.testing.assert_allclose(
            nb.quat_rotate(*q[i], *v[i]), rot.quat_rotate(q[i], v[i]), atol=TOL
        )
        np.testing.assert_allclose(nb.quat_to_ypr(*q[i]), ypr[i], atol=1e-12)
        assert nb.rotation_angle(*q[i]) == pytest.approx(rot.rotation_angle(q[i]), abs=TOL)
        for scale in (1.0, 1e-9):  # the series branch too
            np.testing.assert_allclose(
                nb.quat_from_rotvec(*(scale * v[i])), rot.quat_from_rotvec(scale * v[i]), atol=TOL
            )
    lock = rot.quat_from_ypr([0.7, np.pi / 2, 0.0])
    np.testing.assert_allclose(nb.quat_to_ypr(*lock), rot.quat_to_ypr(lock), atol=1e-7)
