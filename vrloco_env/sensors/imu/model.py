"""The head IMU of B users (:class:`HeadImu`): true motion in, accelerometer, gyroscope and
magnetometer samples out (:class:`ImuSamples`), in one compiled loop per user
(:mod:`vrloco_env.sensors.imu._kernel`). The measurement model: :mod:`vrloco_env.sensors.imu`."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.batching import TakesUsers, stream_rows
from estimators.kernels import param_record, state_records
from estimators.rotations import GRAVITY
from vrloco_env.batch_rng import BatchRng
from vrloco_env.sensors.imu import _kernel
from vrloco_env.sensors.imu.magnetism import EarthField, MagneticDisturbance, _dipole_records
from vrloco_env.sensors.imu.spec import MAX_RATE_HZ, ImuSpec, SensorSpec, get_imu_spec

__all__ = ["HeadImu", "ImuSamples"]

#: Normal draws per sample: white noise, Gauss-Markov drive, random-walk drive, 3 sensors x 3 axes.
_DRAWS_PER_SAMPLE = _kernel.DRAWS_PER_SAMPLE  # 27
#: Normal draws at reset: turn-on biases 9, Gauss-Markov initial states 9, hard iron 3, soft iron 6.
_DRAWS_PER_RESET = 27


class ImuSamples(NamedTuple):
    """IMU outputs (or per-sample biases) of B users over N samples, each ``(B, N, 3)`` float64.

    Attributes:
        acc: specific force (m/s^2), body frame.
        gyr: angular rate (rad/s), body frame.
        mag: magnetic field (uT), body frame.
    """

    acc: NDArray[np.float64]
    gyr: NDArray[np.float64]
    mag: NDArray[np.float64]


def _batch_shaped(x: ArrayLike, name: str, b: int, last: int, n: int) -> NDArray[np.float64]:
    """``x`` as a C-contiguous float64 array of shape (b, n, last), or a ValueError naming it.

    Only the shape is checked here; the values are checked in one compiled pass
    (:func:`vrloco_env.sensors.imu._kernel.first_invalid`).
    """
    a = np.asarray(x, dtype=np.float64)
    if a.ndim != 3 or a.shape[0] != b or a.shape[1] != n or a.shape[2] != last:
        raise ValueError(
            f"{name} must have shape ({b}, {n}, {last}) (B users, N samples), got {a.shape}"
        )
    return _kernel_layout(a)


#: SensorSpec fields the kernel does not read: it reads ``range`` and ``resolution`` and the
#: values :func:`_sensor_record` derives from the others.
_SENSOR_UNREAD = ("noise_density", "bias_stability", "bias_tau", "bias_walk", "turn_on_bias")


def _sensor_record(sens: SensorSpec, dt: float, rate_hz: float) -> NDArray:
    """The kernel's (1,) parameter record of one sensor sampled every ``dt`` s (at ``rate_hz``):
    its ``range`` and ``resolution``, the Gauss-Markov pole ``a = exp(-dt / tau)`` and drive std
    ``sigma sqrt(1 - a^2)``, the random-walk drive std ``K sqrt(dt)`` and the white-noise std per
    sample (unit of the sensor)."""
    a = math.exp(-dt / sens.bias_tau)
    return param_record(
        sens,
        exclude=_SENSOR_UNREAD,
        pole=a,
        gm_std=sens.bias_stability * math.sqrt(max(0.0, 1.0 - a * a)),
        rw_std=sens.bias_walk * math.sqrt(dt),
        noise_std=sens.noise_std(rate_hz),
    )


def _kernel_layout(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """``a`` itself when C-contiguous and writeable, else a copy that is: the one array type the
    kernels are compiled for (numba types strided and read-only arrays apart, each a compilation).
    """
    if a.flags.c_contiguous and a.flags.writeable:
        return a
    return np.array(a, dtype=np.float64, order="C")


#: Stand-in for ``pos`` when none is given (the kernel reads positions only with disturbances).
#: Left writeable: numba types a read-only array apart, which would compile the kernel twice.
_NO_POS = np.zeros((0, 0, 3))
_NO_TIMES = np.zeros((0, 0))

#: Messages of the kernel's input check, by its return code.
_INVALID = {
    _kernel.BAD_QUAT: "quat contains NaN or infinite entries",
    _kernel.ZERO_QUAT: "quat contains a zero-norm quaternion; a rotation needs |q| > 0",
    _kernel.BAD_OMEGA: "omega contains NaN or infinite entries",
    _kernel.BAD_ACC: "acc_world contains NaN or infinite entries",
    _kernel.BAD_POS: "pos contains NaN or infinite entries",
}


class HeadImu(TakesUsers):
    """A head-worn 9-axis IMU for B users, streaming: biases carry over between calls.

    Args:
        spec: an :class:`ImuSpec` or a preset name (see :data:`PRESETS`).
        rng: one random stream per user; B = ``rng.batch_size``. The IMU draws nothing else from
            it than what :meth:`reset` and :meth:`sample` need, in a fixed order, so a batch
            reproduces B single-user runs bit for bit.
        rate_hz: sample rate (Hz) in (0, 1000]; default 100 Hz.
        field: the undisturbed geomagnetic field.
        disturbances: magnetic dipoles in the world (metal obstacles).

    Attributes:
        samples_taken: (B,) int64, samples synthesised per user since that user's last
            :meth:`reset`.
        last_bias: per-sample total additive biases of the last :meth:`sample` call
            (:class:`ImuSamples`, each (B, N, 3); the magnetometer's includes hard iron), or None
            after a reset of all users. A reset of some users leaves it as it was (it describes
            that call's samples; :attr:`bias` gives the current biases).

    The constructor calls :meth:`reset` for all users. ``reset(users=...)`` redraws only the given
    users, from their own streams, so one user of a batch can start a new episode while the others
    carry on.
    """

    # each user's bias states and clock (the random streams belong to the caller's BatchRng)
    per_user_fields = ("_state", "samples_taken", "last_bias")

    def __init__(
        self,
        spec: str | ImuSpec,
        rng: BatchRng,
        rate_hz: float = 100.0,
        field: EarthField | None = None,
        disturbances: Sequence[MagneticDisturbance] = (),
    ) -> None:
        self.spec = get_imu_spec(spec)
        if not isinstance(rng, BatchRng):
            raise ValueError(
                f"rng must be a vrloco_env.batch_rng.BatchRng, got {type(rng).__name__}"
            )
        try:
            rate = float(rate_hz)
        except (TypeError, ValueError):
            raise ValueError(f"rate_hz must be a number in (0, {MAX_RATE_HZ:g}] Hz") from None
        if not (0.0 < rate <= MAX_RATE_HZ):
            raise ValueError(f"rate_hz must be in (0, {MAX_RATE_HZ:g}] Hz, got {rate_hz!r}")
        field = EarthField() if field is None else field
        if not isinstance(field, EarthField):
            raise ValueError(f"field must be an EarthField, got {type(field).__name__}")
        disturbances = tuple(disturbances)
        for i, d in enumerate(disturbances):
            if not isinstance(d, MagneticDisturbance):
                raise ValueError(
                    f"disturbances[{i}] must be a MagneticDisturbance, got {type(d).__name__}"
                )
        self.rng = rng
        self.rate_hz = rate
        self.dt = 1.0 / rate
        self.field = field
        self.disturbances = disturbances
        self._field_world = field.vector_enu()
        # The kernel's parameter records (vrloco_env.sensors.imu._kernel), built once here.
        self._sensors = np.concatenate(
            [
                _sensor_record(sens, self.dt, rate)
                for sens in (self.spec.accel, self.spec.gyro, self.spec.mag)
            ]
        )
        east, north, up = self._field_world
        self._earth = param_record(east=east, north=north, up=up)
        self._dipoles = _dipole_records(disturbances)
        self.reset()

    @property
    def batch_size(self) -> int:
        """B, the number of users."""
        return self.rng.batch_size

    @property
    def gravity_world(self) -> NDArray[np.float64]:
        """The gravity vector the model uses, ``[0, 0, -GRAVITY]`` (m/s^2), (3,)."""
        return np.array([0.0, 0.0, -GRAVITY])

    @property
    def field_world(self) -> NDArray[np.float64]:
        """The undisturbed reference field in ENU (uT), (3,): what an estimator may assume."""
        return self._field_world.copy()

    def reset(self, users: ArrayLike | None = None) -> None:
        """Draw turn-on biases, hard/soft iron and initial bias states for some or all users.

        Each reset user draws one block of 27 normals from its own stream (turn-on biases 9,
        Gauss-Markov initial states 9, hard iron 3, soft iron 6); its random walks restart at 0
        and its :attr:`samples_taken` at 0. The other users' state and streams are untouched, so
        after ``rng.reseed(i, g)`` and ``reset(users=[i])`` user i continues exactly as a fresh
        single-user ``HeadImu`` on ``BatchRng([g])`` would (a vector env's autoreset).

        Args:
            users: the users to reset, as indices or a (B,) boolean mask; None resets all.

        Raises:
            ValueError: an index outside [0, B), a repeated index or a mask of the wrong shape.
        """
        b = self.batch_size
        rows = stream_rows(users, b)
        if users is None or not hasattr(self, "_state"):  # first call: allocate every user
            self._state = state_records(_kernel.STATE, b)
            self._state["soft_iron"] = np.eye(3)
            self.samples_taken = np.zeros(b, dtype=np.int64)
            self.last_bias: ImuSamples | None = None
        r = rows.size
        spec = self.spec
        st = self._state
        z = self.rng.normal((_DRAWS_PER_RESET,), rows=rows)  # (r, 27)
        sensors = (spec.accel, spec.gyro, spec.mag)
        turn_on = z[:, 0:9].reshape(r, 3, 3)
        gm0 = z[:, 9:18].reshape(r, 3, 3)
        st["turn_on"][rows] = np.stack(
            [turn_on[:, i] * s.turn_on_bias for i, s in enumerate(sensors)], 1
        )
        st["gm"][rows] = np.stack([gm0[:, i] * s.bias_stability for i, s in enumerate(sensors)], 1)
        st["rw"][rows] = 0.0
        st["hard_iron"][rows] = z[:, 18:21] * spec.hard_iron
        diag = z[:, 21:24] * spec.soft_iron_scale
        off = z[:, 24:27] * spec.soft_iron_cross
        s = np.zeros((r, 3, 3))
        s[:, 0, 0] = 1.0 + diag[:, 0]
        s[:, 1, 1] = 1.0 + diag[:, 1]
        s[:, 2, 2] = 1.0 + diag[:, 2]
        s[:, 0, 1] = s[:, 1, 0] = off[:, 0]
        s[:, 0, 2] = s[:, 2, 0] = off[:, 1]
        s[:, 1, 2] = s[:, 2, 1] = off[:, 2]
        st["soft_iron"][rows] = s
        self.samples_taken[rows] = 0

    @property
    def bias(self) -> ImuSamples:
        """Current total additive bias per user, each (B, 3): turn-on + Gauss-Markov + walk.

        For the magnetometer this includes the hard-iron offset (uT); the soft-iron matrix is
        multiplicative and lives in :attr:`soft_iron`. After :meth:`sample` these are the biases of
        its last sample.
        """
        st = self._state
        tot = st["turn_on"] + st["gm"] + st["rw"]
        return ImuSamples(tot[:, 0].copy(), tot[:, 1].copy(), tot[:, 2] + st["hard_iron"])

    @property
    def hard_iron(self) -> NDArray[np.float64]:
        """Hard-iron offset per user (uT), (B, 3)."""
        return self._state["hard_iron"].copy()

    @property
    def soft_iron(self) -> NDArray[np.float64]:
        """Soft-iron matrix per user (dimensionless), (B, 3, 3), applied to the body-frame field."""
        return self._state["soft_iron"].copy()

    def sample_times(self, n: int) -> NDArray[np.float64]:
        """The times (s since each user's reset) of the next ``n`` samples, (B, n): sample ``s``
        of an episode (from 0) is taken at ``(s + 1) / rate_hz``."""
        return (self.samples_taken[:, None] + np.arange(1, n + 1)[None, :]) * self.dt

    def true_field_world(
        self, pos: ArrayLike | None, shape: tuple[int, int]
    ) -> NDArray[np.float64]:
        """True world-frame field (uT) at the IMU for the next ``shape[1]`` samples
        (:meth:`sample_times`): earth field plus every dipole's field where it is then.

        Args:
            pos: IMU positions in the world (m), (B, N, 3); may be None without disturbances.
            shape: (B, N).

        Returns:
            (B, N, 3) field in ENU (uT).
        """
        m = np.broadcast_to(self._field_world, (*shape, 3)).copy()
        times = self.sample_times(shape[1])
        for d in self.disturbances:  # a handful of objects, not a batch or time loop
            m = m + d.field_at(pos, times)
        return m

    def sample(
        self,
        quat: ArrayLike,
        omega: ArrayLike,
        acc_world: ArrayLike,
        pos: ArrayLike | None = None,
    ) -> ImuSamples:
        """Synthesize N successive samples for each of the B users.

        One call of :data:`vrloco_env.sensors.imu._kernel.sample_kernel` after the input checks.

        Args:
            quat: true sensor -> world orientations, (B, N, 4) Hamilton [w, x, y, z] (normalised
                here; must be finite and non-zero).
            omega: true body-frame angular rates (rad/s), (B, N, 3).
            acc_world: true linear acceleration of the sensor in the world (m/s^2), gravity NOT
                included, (B, N, 3).
            pos: sensor positions in the world (m), (B, N, 3); required only with disturbances.

        Returns:
            :class:`ImuSamples` with acc (m/s^2), gyr (rad/s), mag (uT), each (B, N, 3) float64.
            The per-sample total biases are kept in :attr:`last_bias`.

        Raises:
            ValueError: a wrong shape, a non-finite entry, a zero quaternion, or ``pos`` missing
                with disturbances. Nothing is drawn and no state changes when it raises.
        """
        b = self.batch_size
        q = np.asarray(quat, dtype=np.float64)
        if q.ndim != 3 or q.shape[0] != b or q.shape[2] != 4:
            raise ValueError(
                f"quat must have shape ({b}, N, 4) (B users, N samples), got {q.shape}"
            )
        q = _kernel_layout(q)
        n = q.shape[1]
        w = _batch_shaped(omega, "omega", b, 3, n)
        a = _batch_shaped(acc_world, "acc_world", b, 3, n)
        if pos is not None:
            p = _batch_shaped(pos, "pos", b, 3, n)
        elif self.disturbances:
            raise ValueError("pos (B, N, 3) in m is required when magnetic disturbances are set")
        else:
            p = _NO_POS
        times = self.sample_times(n) if self.disturbances else _NO_TIMES
        code = _kernel.first_invalid(q, w, a, p)
        if code != _kernel.OK:
            raise ValueError(_INVALID[code])

        z = self.rng.normal((n, _DRAWS_PER_SAMPLE))  # (B, N, 27), time-major: streams chunk-safe
        out = np.empty((6, b, n, 3))
        _kernel.sample_kernel(b)(
            q, w, a, p, times, z, self._sensors, self._earth, self._dipoles, self._state, out
        )
        self.samples_taken += n  # every user advances by the same N samples
        self.last_bias = ImuSamples(out[3], out[4], out[5])
        return ImuSamples(out[0], out[1], out[2])
