"""The error-state EKF's compiled kernel (the filter is derived in :mod:`estimators.attitude.ekf`).

One sample of one stream is :func:`_step`, cut into the stages of the filter: initialisation
(:func:`_initialise_tilt`, :func:`_initialise_heading`), gyro propagation (:func:`_gyro_step`),
accelerometer update (:func:`_accelerometer_update`), magnetometer update
(:func:`_magnetometer_gate`, :func:`_magnetometer_update`), zero-rate update at rest
(:func:`_rest_update`) and injection of the error state (:func:`_inject`); or, in place of the
last four, the measurement update as Zhang 2021 prints it (:func:`_printed_update`: Euler-angle
residuals, constant R, compensation of the Euler angles). The stages are inlined into the loop
over samples. :data:`ekf_kernel` loops over streams outside and samples inside, so each stream's
state stays in cache while its samples are processed; its uncompiled ``py_func`` is the readable
reference.

Named records (:mod:`estimators.kernels.records`): the parameters ``prm`` are a (1,) record of the
fields of :class:`~estimators.attitude.ekf.AttitudeParams` read here, plus two switches,
``trawny`` (1.0: the error dynamics of Trawny, 0.0: the paper's printed ``F = 0``) and
``printed_meas`` (1.0: the measurement update as printed, 0.0: the corrected one with its
robustness), ``dt`` (s), and the unit guard's ``max_gyr_norm2``, ``min_acc_norm2`` (squared
limits) and ``unit_min_count``. Each stream's state is a record of :data:`STATE_FIELDS`, its
scratch memory a record of :data:`SCRATCH_FIELDS`.
Quaternions are Hamilton ``[w, x, y, z]``, sensor -> ENU world.

The arguments are plain structured arrays, not ``np.recarray`` views (numba's dispatcher probes a
recarray through its Python-level attribute lookup on every call). Their elements (``np.void``)
have no attribute access in Python, so the Python source of :data:`ekf_kernel` reads the records
only inside the stages, which stay compiled under :func:`estimators.kernels.python_reference`.
"""

from __future__ import annotations

import math

import numba

from estimators.kernels.batch import BatchKernel
from estimators.kernels.rotations import (
    quat_from_rotvec,
    quat_from_ypr,
    quat_mul,
    quat_to_ypr,
    rotation_matrix,
    wrap_angle,
)

__all__ = ["SCRATCH_FIELDS", "STATE_FIELDS", "ekf_kernel"]

#: Per-stream filter state (float64 record fields and their shapes).
STATE_FIELDS = {
    "q": (4,),  # nominal quaternion, sensor -> ENU
    "b": (3,),  # gyro bias estimate, rad/s
    # Error-state covariance, [dphi (rad), db (rad/s)]; under the printed measurement model dphi
    # are the Euler-angle errors [pitch, roll, yaw] (rad) of Zhang 2021 eq (6).
    "P": (6, 6),
    "init": (),  # 1.0 once the attitude has been initialised from an accelerometer sample
    "head_init": (),  # 1.0 once the heading has been initialised from a magnetometer sample
    "mag_norm": (),  # reference field norm (field unit)
    "mag_dip": (),  # reference dip angle (rad), positive when the field points below the horizon
    "mag_learn_n": (),  # samples averaged into the reference so far
    "mag_learn_t": (),  # s spent learning so far (inf: reference given, no learning)
    "cand_norm": (),  # candidate new field norm
    "cand_dip": (),  # candidate new field dip (rad)
    "cand_t": (),  # s the candidate has stayed consistent while the reference was rejected
    "mag_ok_t": (),  # s the field has stayed consistent with the reference
    "motion": (),  # low-passed | |f| - g | (m/s^2); corrected measurement model only
    "rest_t": (),  # s the sensor has looked at rest; corrected measurement model only
    "n_seen": (),  # unit guard: finite accelerometer samples
    "n_gyr_big": (),  # unit guard: gyro samples above max_gyr_norm
    "n_acc_small": (),  # unit guard: accelerometer samples below min_acc_norm
}

#: Per-stream scratch memory of one step (contents meaningless between steps).
SCRATCH_FIELDS = {
    "dx": (6,),  # error state [dphi, db]
    "Rm": (3, 3),  # rotation matrix of q
    "M": (3, 3),  # attitude block I - [w x] dt of the transition matrix
    "ma": (3, 9),  # products M P (columns 0-5) and M A M^T (columns 6-8)
    "ph": (6,),  # P H^T of a scalar measurement
}


# ------------------------------------------------------------------------------------------------
# Small helpers: quaternion updates and the covariance algebra.
# ------------------------------------------------------------------------------------------------


@numba.njit(cache=True, inline="always")
def _quat_mul_rotvec(q, rx, ry, rz):
    """In place ``q <- normalize(q ⊗ exp([rx, ry, rz]))`` (rotation vector in rad, body frame)."""
    pw, px, py, pz = quat_from_rotvec(rx, ry, rz)
    nw, nx, ny, nz = quat_mul(q[0], q[1], q[2], q[3], pw, px, py, pz)
    n = math.sqrt(nw * nw + nx * nx + ny * ny + nz * nz)
    q[0], q[1], q[2], q[3] = nw / n, nx / n, ny / n, nz / n


@numba.njit(cache=True, inline="always")
def _yaw_rotate(q, angle):
    """In place ``q <- Rz(angle) ⊗ q``: turn the attitude about the world vertical (rad)."""
    c = math.cos(0.5 * angle)
    s = math.sin(0.5 * angle)
    w, x, y, z = q[0], q[1], q[2], q[3]
    q[0] = c * w - s * z
    q[1] = c * x - s * y
    q[2] = c * y + s * x
    q[3] = c * z + s * w


@numba.njit(cache=True, inline="always")
def _scalar_update(P, dx, h, z, r, ph):
    """One scalar Kalman update with ``H = [h, 0, 0, 0]`` (h acts on dphi only).

    Eq. (14) of Zhang 2021, ``dx+ = dx- + K (z - H dx-)``, processed one measurement row at a time
    (equivalent to the joint update for a diagonal R), and ``P+ = P- - K H P-`` computed on the
    upper triangle and mirrored (P stays exactly symmetric). ``ph`` is (6,) scratch.
    """
    for i in range(6):
        ph[i] = P[i, 0] * h[0] + P[i, 1] * h[1] + P[i, 2] * h[2]
    s = h[0] * ph[0] + h[1] * ph[1] + h[2] * ph[2] + r
    innov = (z - (h[0] * dx[0] + h[1] * dx[1] + h[2] * dx[2])) / s
    for i in range(6):
        dx[i] += ph[i] * innov
        ki = ph[i] / s
        for j in range(i, 6):
            v = P[i, j] - ki * ph[j]
            P[i, j] = v
            P[j, i] = v


@numba.njit(cache=True, inline="always")
def _component_update(P, dx, k, z, r, ph):
    """One scalar Kalman update measuring error-state component k: ``H = e_k`` (in place)."""
    for i in range(6):
        ph[i] = P[i, k]
    s = ph[k] + r
    innov = (z - dx[k]) / s
    for i in range(6):
        dx[i] += ph[i] * innov
        ki = ph[i] / s
        for k in range(i, 6):
            v = P[i, k] - ki * ph[k]
            P[i, k] = v
            P[k, i] = v


@numba.njit(cache=True, inline="always")
def _propagate_cov(P, M, dt, ma):
    """``P <- Phi P Phi^T`` for ``Phi = [[M, -dt I], [0, I]]``, by 3x3 blocks.

    With ``P = [[A, C], [C^T, D]]``: ``C' = M C - dt D``,
    ``A' = M A M^T - dt ((M C)^T + C')``, ``D' = D``.
    """
    for i in range(3):
        for j in range(6):
            ma[i, j] = M[i, 0] * P[0, j] + M[i, 1] * P[1, j] + M[i, 2] * P[2, j]
    for i in range(3):
        for j in range(3):
            c_new = ma[i, 3 + j] - dt * P[3 + i, 3 + j]
            P[i, 3 + j] = c_new
            P[3 + j, i] = c_new
    for i in range(3):
        for j in range(3):
            ma[i, 6 + j] = ma[i, 0] * M[j, 0] + ma[i, 1] * M[j, 1] + ma[i, 2] * M[j, 2]
    for i in range(3):
        for j in range(i, 3):
            a_new = ma[i, 6 + j] - dt * (ma[j, 3 + i] + P[i, 3 + j])
            P[i, j] = a_new
            P[j, i] = a_new


# ------------------------------------------------------------------------------------------------
# The stages of one step. s: the stream's state record, c: its scratch record, p: the parameters.
# ------------------------------------------------------------------------------------------------


@numba.njit(cache=True, inline="always")
def _initialise_tilt(s, p, w, f, fn, w_ok, f_ok, dt):
    """Before initialisation: set the tilt from the first accelerometer sample within g/2 of g
    (``fn`` its norm), else integrate the gyro from the current attitude."""
    g = p.gravity
    q, P = s.q, s.P
    if f_ok and abs(fn - g) < 0.5 * g:
        # Tilt: the shortest rotation taking the measured up (f/|f|, sensor) to world +z.
        ux, uy, uz = f[0] / fn, f[1] / fn, f[2] / fn
        if uz > -1.0 + 1e-9:
            qw = math.sqrt(0.5 * (1.0 + uz))
            q[0], q[1], q[2], q[3] = qw, uy / (2.0 * qw), -ux / (2.0 * qw), 0.0
        else:
            q[0], q[1], q[2], q[3] = 0.0, 1.0, 0.0, 0.0
        for i in range(6):
            for j in range(6):
                P[i, j] = 0.0
        for i in range(3):
            s.b[i] = 0.0
            P[i, i] = p.att_init_std**2
            P[i + 3, i + 3] = p.bias_init_std**2
        s.init = 1.0
        s.motion = abs(fn - g)
    elif w_ok:
        _quat_mul_rotvec(q, w[0] * dt, w[1] * dt, w[2] * dt)


@numba.njit(cache=True, inline="always")
def _initialise_heading(s, p, f, m, Rm):
    """Set the heading: turn about the world vertical until the measured east (m x f in the
    sensor: north x up = east, the tilt-compensated compass of eq (12) as a vector) points along
    the magnetic east of ENU, at yaw -D from +x. ``Rm`` is (3, 3) scratch."""
    q = s.q
    ex = m[1] * f[2] - m[2] * f[1]
    ey = m[2] * f[0] - m[0] * f[2]
    ez = m[0] * f[1] - m[1] * f[0]
    rotation_matrix(q[0], q[1], q[2], q[3], Rm)
    e_wx = Rm[0, 0] * ex + Rm[0, 1] * ey + Rm[0, 2] * ez
    e_wy = Rm[1, 0] * ex + Rm[1, 1] * ey + Rm[1, 2] * ez
    if e_wx * e_wx + e_wy * e_wy > 0.0:
        _yaw_rotate(q, wrap_angle(-p.declination - math.atan2(e_wy, e_wx)))
        s.head_init = 1.0


@numba.njit(cache=True, inline="always")
def _gyro_step(s, c, p, w, w_ok, dt):
    """Propagation: ``q_dot = 1/2 q ⊗ (y - b)``, eqs (3)-(5); ``P <- Phi P Phi^T + Q dt`` with
    ``Phi = I + F dt``, eq (9) (``Phi = I`` under the printed ``F = 0``: ``P <- P + Q dt``). A
    non-finite gyro sample skips the rotation and inflates the attitude variance by the rotation
    missed, ``(gyr_gap_rate dt)^2``."""
    q, b, P = s.q, s.b, s.P
    if w_ok:
        wx, wy, wz = w[0] - b[0], w[1] - b[1], w[2] - b[2]
        if p.trawny != 0.0:
            # M = I - [w x] dt, the attitude block of I + F dt.
            M = c.M
            M[0, 0], M[0, 1], M[0, 2] = 1.0, wz * dt, -wy * dt
            M[1, 0], M[1, 1], M[1, 2] = -wz * dt, 1.0, wx * dt
            M[2, 0], M[2, 1], M[2, 2] = wy * dt, -wx * dt, 1.0
            _propagate_cov(P, M, dt, c.ma)
        _quat_mul_rotvec(q, wx * dt, wy * dt, wz * dt)
    qg = p.gyr_noise**2 * dt
    if not w_ok:
        qg += (p.gyr_gap_rate * dt) ** 2  # the rotation missed during the gap
    qb = p.bias_walk**2 * dt
    for i in range(3):
        P[i, i] += qg
        P[i + 3, i + 3] += qb


@numba.njit(cache=True, inline="always")
def _accelerometer_update(s, c, p, f, fn, dt):
    """Tilt measurement: the horizontal part of the specific force in the world over g, weighted
    down by the motion level (``| |f| - g |`` low-passed over ``motion_tau``)."""
    g = p.gravity
    Rm = c.Rm
    s.motion += min(1.0, dt / p.motion_tau) * (abs(fn - g) - s.motion)
    lvl = s.motion / p.acc_motion_ref
    r = p.acc_noise**2 * (1.0 + lvl * lvl) / dt
    ax = Rm[0, 0] * f[0] + Rm[0, 1] * f[1] + Rm[0, 2] * f[2]
    ay = Rm[1, 0] * f[0] + Rm[1, 1] * f[1] + Rm[1, 2] * f[2]
    _scalar_update(s.P, c.dx, Rm[0], ay / g, r, c.ph)
    _scalar_update(s.P, c.dx, Rm[1], -ax / g, r, c.ph)


@numba.njit(cache=True, inline="always")
def _magnetometer_gate(s, p, mn, dip, dt):
    """Learn the reference field, or check a sample (norm ``mn``, dip ``dip``) against it.

    During the first ``mag_learn_time`` seconds the reference norm and dip are running means and
    every sample is used. Then a sample is used once the field has agreed with the reference for
    ``mag_ok_time``; a disturbed field that stays self-consistent for ``mag_new_time`` becomes the
    reference. Returns whether the sample is used.
    """
    if s.mag_learn_t < p.mag_learn_time:
        n_l = s.mag_learn_n + 1.0
        s.mag_norm += (mn - s.mag_norm) / n_l
        s.mag_dip += (dip - s.mag_dip) / n_l
        s.mag_learn_n = n_l
        s.mag_learn_t += dt
        return True
    ref_n, ref_d = s.mag_norm, s.mag_dip
    if abs(mn - ref_n) <= p.mag_norm_tol * ref_n and abs(dip - ref_d) <= p.mag_dip_tol:
        s.cand_t = 0.0
        s.mag_ok_t += dt
        return s.mag_ok_t >= p.mag_ok_time
    c_n, c_d = s.cand_norm, s.cand_dip
    if s.cand_t > 0.0 and abs(mn - c_n) <= p.mag_norm_tol * c_n and abs(dip - c_d) <= p.mag_dip_tol:
        s.cand_t += dt
        a_c = min(1.0, dt / p.motion_tau)
        s.cand_norm += a_c * (mn - c_n)
        s.cand_dip += a_c * (dip - c_d)
    else:
        s.cand_norm, s.cand_dip, s.cand_t = mn, dip, dt
    if s.cand_t >= p.mag_new_time:
        s.mag_norm, s.mag_dip = s.cand_norm, s.cand_dip
        s.cand_t = 0.0
        s.mag_ok_t = p.mag_ok_time
        return True
    s.mag_ok_t = 0.0
    return False


@numba.njit(cache=True, inline="always")
def _magnetometer_update(s, c, p, m, mn, dt):
    """Heading measurement, eqs (12)-(13): the field (norm ``mn``) rotated into the world by the
    predicted attitude; magnetic north lies at yaw pi/2 - D in ENU, the residual is wrapped into
    (-pi, pi]. Returns whether the measurement was applied."""
    Rm = c.Rm
    mx = (Rm[0, 0] * m[0] + Rm[0, 1] * m[1] + Rm[0, 2] * m[2]) / mn
    my = (Rm[1, 0] * m[0] + Rm[1, 1] * m[1] + Rm[1, 2] * m[2]) / mn
    mz = (Rm[2, 0] * m[0] + Rm[2, 1] * m[1] + Rm[2, 2] * m[2]) / mn
    dip = math.asin(min(1.0, max(-1.0, -mz)))
    accept = _magnetometer_gate(s, p, mn, dip, dt)
    if accept and mx * mx + my * my > 1e-6:
        zpsi = wrap_angle(0.5 * math.pi - p.declination - math.atan2(my, mx))
        _scalar_update(s.P, c.dx, Rm[2], zpsi, p.mag_noise**2 / dt, c.ph)
        return True
    return False


@numba.njit(cache=True, inline="always")
def _rest_update(s, c, p, w, fn, dt):
    """Zero-rate update: after ``rest_time`` with a small bias-corrected rate and ``| |f| - g |``
    (``fn`` the accelerometer norm) the gyro reads its bias, ``z = y - b``, ``H = [0 I]``.
    Returns whether the update was applied."""
    b = s.b
    wx, wy, wz = w[0] - b[0], w[1] - b[1], w[2] - b[2]
    still = abs(fn - p.gravity) < p.rest_acc and wx * wx + wy * wy + wz * wz < p.rest_gyr**2
    s.rest_t = s.rest_t + dt if still else 0.0
    if s.rest_t >= p.rest_time:
        r_b = p.gyr_noise**2 / dt
        _component_update(s.P, c.dx, 3, w[0] - b[0], r_b, c.ph)
        _component_update(s.P, c.dx, 4, w[1] - b[1], r_b, c.ph)
        _component_update(s.P, c.dx, 5, w[2] - b[2], r_b, c.ph)
        return True
    return False


@numba.njit(cache=True, inline="always")
def _inject(s, dx):
    """Inject and reset: ``q <- q ⊗ exp(dphi)``, ``b <- b + db`` (``dx`` is zeroed next step)."""
    _quat_mul_rotvec(s.q, dx[0], dx[1], dx[2])
    b = s.b
    b[0] += dx[3]
    b[1] += dx[4]
    b[2] += dx[5]


@numba.njit(cache=True, inline="always")
def _printed_update(s, c, p, f, m, use_mag):
    """The measurement update as printed, eqs (2) and (10)-(14), for the accelerometer sample
    ``f`` and, if ``use_mag``, the magnetometer sample ``m`` (derivation and reading of the
    printed equations: :mod:`estimators.attitude.ekf`).

    The error state is ``dx = [dtheta, dgamma, dpsi, db]`` (pitch, roll, yaw errors, estimate
    minus truth, eq 6), measured by ``z = [theta - theta_acc, gamma - gamma_acc,
    psi - psi_compass]`` with ``H = [I 0]`` and the constant ``R = diag(acc_noise^2,
    acc_noise^2, mag_noise^2) / dt``; eq (14) one row at a time; then the compensation
    ``[theta, gamma, psi] <- [theta, gamma, psi] - dphi``, ``b <- b - db`` and back to q.
    """
    q, P, dx, ph = s.q, s.P, c.dx, c.ph
    psi, theta, gamma = quat_to_ypr(q[0], q[1], q[2], q[3])  # eq (2), the prior angles
    # Eq (11): pitch and roll from the specific force (f = g [-sin theta, cos theta sin gamma,
    # cos theta cos gamma] in our frame).
    theta_acc = math.atan2(-f[0], math.sqrt(f[1] * f[1] + f[2] * f[2]))
    gamma_acc = math.atan2(f[1], f[2])
    r_acc = p.acc_noise**2 / p.dt
    _component_update(P, dx, 0, theta - theta_acc, r_acc, ph)
    _component_update(P, dx, 1, wrap_angle(gamma - gamma_acc), r_acc, ph)
    if use_mag:
        # Eq (12): the field levelled with the accelerometer's pitch and roll; eq (13): the
        # compass yaw, magnetic north at yaw pi/2 - D in ENU.
        ct, st = math.cos(theta_acc), math.sin(theta_acc)
        cg, sg = math.cos(gamma_acc), math.sin(gamma_acc)
        hx = m[0] * ct + m[1] * st * sg + m[2] * st * cg
        hy = m[1] * cg - m[2] * sg
        if hx * hx + hy * hy > 1e-6 * (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]):
            psi_compass = 0.5 * math.pi - p.declination - math.atan2(hy, hx)
            _component_update(P, dx, 2, wrap_angle(psi - psi_compass), p.mag_noise**2 / p.dt, ph)
    # Compensation (section 1, Fig 1): the posterior angles, converted back to the quaternion.
    qw, qx, qy, qz = quat_from_ypr(psi - dx[2], theta - dx[0], gamma - dx[1])
    n = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    q[0], q[1], q[2], q[3] = qw / n, qx / n, qy / n, qz / n
    b = s.b
    b[0] -= dx[3]
    b[1] -= dx[4]
    b[2] -= dx[5]


@numba.njit(cache=True, inline="always")
def _step(s, c, p, w, f, m):
    """Advance one stream by one sample (gyro ``w`` rad/s, accelerometer ``f`` m/s^2,
    magnetometer ``m`` any unit, each (3,); a non-finite sample skips its sensor)."""
    dt = p.dt
    w_ok = math.isfinite(w[0]) and math.isfinite(w[1]) and math.isfinite(w[2])
    f_ok = math.isfinite(f[0]) and math.isfinite(f[1]) and math.isfinite(f[2])
    m_ok = math.isfinite(m[0]) and math.isfinite(m[1]) and math.isfinite(m[2])
    fn = math.sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]) if f_ok else 0.0
    mn = math.sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]) if m_ok else 0.0
    f_ok = f_ok and fn > 0.0
    m_ok = m_ok and mn > 0.0

    if s.init == 0.0:
        _initialise_tilt(s, p, w, f, fn, w_ok, f_ok, dt)
        if s.init == 0.0:
            return
    if s.head_init == 0.0 and m_ok and f_ok:
        _initialise_heading(s, p, f, m, c.Rm)

    _gyro_step(s, c, p, w, w_ok, dt)

    dx = c.dx
    for i in range(6):
        dx[i] = 0.0
    if p.printed_meas != 0.0:
        if f_ok:
            _printed_update(s, c, p, f, m, m_ok and s.head_init != 0.0)
        return
    q = s.q
    rotation_matrix(q[0], q[1], q[2], q[3], c.Rm)
    updated = False
    if f_ok:
        _accelerometer_update(s, c, p, f, fn, dt)
        updated = True
    if m_ok and s.head_init != 0.0:
        updated = _magnetometer_update(s, c, p, m, mn, dt) or updated
    if w_ok and f_ok:
        updated = _rest_update(s, c, p, w, fn, dt) or updated
    if updated:
        _inject(s, dx)


@numba.njit(cache=True, inline="always")
def _count_units(s, p, w, f):
    """Unit guard (not part of the filter): count the finite accelerometer samples, those below
    ``min_acc_norm`` and the gyro samples above ``max_gyr_norm`` (limits squared in ``p``)."""
    a2 = f[0] * f[0] + f[1] * f[1] + f[2] * f[2]
    if math.isfinite(a2):
        s.n_seen += 1.0
        if a2 < p.min_acc_norm2:
            s.n_acc_small += 1.0
    if w[0] * w[0] + w[1] * w[1] + w[2] * w[2] > p.max_gyr_norm2:
        s.n_gyr_big += 1.0


@numba.njit(cache=True, inline="always")
def _unit_mixup(s, p):
    """0 if the counters say the gyro is not in rad/s, 1 if the accelerometer is in g, else -1."""
    seen, big, small = s.n_seen, s.n_gyr_big, s.n_acc_small
    if big >= p.unit_min_count and big * 100.0 >= seen:
        return 0
    if small >= p.unit_min_count and small * 2.0 > seen:
        return 1
    return -1


@numba.njit(cache=True, inline="always")
def _emit(s, out):
    """Copy the stream's quaternion into ``out`` (4,)."""
    q = s.q
    out[0] = q[0]
    out[1] = q[1]
    out[2] = q[2]
    out[3] = q[3]


def _ekf_run(state, scratch, gyr, acc, mag, prm, out):
    """Run B independent streams over N samples; ``out[i, n]`` receives q after sample n.

    Args:
        state: (B,) records of :data:`STATE_FIELDS`, updated in place.
        scratch: (B,) records of :data:`SCRATCH_FIELDS`.
        gyr, acc, mag: (B, N, 3) samples (mag all-NaN for a 6D filter).
        prm: (1,) parameter record (see the module docstring).
        out: (B, N, 4) output quaternions.

    Returns:
        -1, or ``2 * i + k`` for the first stream i whose unit-guard counters look like a unit
        mix-up (k = 0: gyro not in rad/s, k = 1: accelerometer in g). The caller raises.
    """
    p = prm[0]
    n_streams, n_samples = gyr.shape[0], gyr.shape[1]
    no_flag = 2 * n_streams
    flag = no_flag
    for i in numba.prange(n_streams):
        s, c = state[i], scratch[i]
        for n in range(n_samples):
            w, f = gyr[i, n], acc[i, n]
            _count_units(s, p, w, f)
            _step(s, c, p, w, f, mag[i, n])
            _emit(s, out[i, n])
        k = _unit_mixup(s, p)
        if k >= 0:
            flag = min(flag, 2 * i + k)
    return -1 if flag == no_flag else flag


#: The EKF over a batch of streams: ``ekf_kernel(B)(state, scratch, gyr, acc, mag, prm, out)``.
#: Serial only: the streams of one call are few or their samples many.
ekf_kernel = BatchKernel(_ekf_run, parallel=False)
