"""Head-worn IMU sensor model: accelerometer, gyroscope and magnetometer for B users at once.

Measurement model (one sample, body frame = sensor frame, conventions of
:mod:`estimators.rotations`: ENU world, Hamilton ``[w, x, y, z]`` sensor -> world):

* accelerometer: ``f = R^T (a - g) + b_a + n_a`` with ``g = [0, 0, -GRAVITY]``, so a static, level
  IMU reads ``[0, 0, +GRAVITY]``;
* gyroscope: ``y = w + b_g + n_g`` with ``w`` the true body-frame angular rate;
* magnetometer: ``m = S R^T (m_earth + sum_k B_k(p)) + h + b_m + n_m`` with ``S`` the soft-iron
  matrix, ``h`` the hard-iron offset and ``B_k`` the fields of magnetic dipoles (metal objects) at
  the IMU position ``p``;

then each output is quantised to its resolution and clipped at its range (saturation).

Every bias ``b`` is the sum of a turn-on bias (constant, drawn at :meth:`HeadImu.reset`), a
first-order Gauss-Markov process ``x_k = a x_{k-1} + sigma sqrt(1 - a^2) u_k`` with
``a = exp(-dt / tau)`` (stationary standard deviation ``sigma`` = the datasheet's bias stability,
initial state drawn from the stationary distribution) and an optional random walk
``r_k = r_{k-1} + K sqrt(dt) u_k``. The recursions run along the time axis from the carried
state, so a stream sampled in chunks equals the same stream sampled at once, bit for bit.

The whole model runs in one compiled loop per user (:mod:`vrloco_env.sensors.imu._kernel`), the
recursions in the order ``scipy.signal.lfilter`` runs them.

White noise follows the discrete-time convention of angle/velocity random walk (IEEE Std 952,
Kalibr's IMU noise model): a noise density ``N`` (unit/sqrt(Hz)) sampled at ``f_s`` gives a
per-sample standard deviation ``N * sqrt(f_s)``. Decision: the same convention is used for the
magnetometer, so its per-sample noise grows with the rate as well; a real magnetometer often has a
fixed per-sample noise set by its measurement time, which the presets' densities are chosen to
match at 100 Hz.

Units: accelerometer m/s^2, gyroscope rad/s, magnetometer microtesla (uT; 1 Gauss = 100 uT),
lengths m, magnetic moments A m^2, rates Hz, angles in the public :class:`EarthField` in degrees.

Modules: :mod:`~vrloco_env.sensors.imu.spec` (sensor specifications and presets),
:mod:`~vrloco_env.sensors.imu.magnetism` (the earth field and magnetic disturbances),
:mod:`~vrloco_env.sensors.imu.model` (the sensor model :class:`HeadImu`) and
:mod:`~vrloco_env.sensors.imu._kernel` (its compiled loop).
"""

from vrloco_env.sensors.imu.magnetism import MU0_OVER_4PI, EarthField, MagneticDisturbance
from vrloco_env.sensors.imu.model import HeadImu, ImuSamples
from vrloco_env.sensors.imu.spec import MAX_RATE_HZ, PRESETS, ImuSpec, SensorSpec, get_imu_spec

__all__ = [
    "MAX_RATE_HZ",
    "MU0_OVER_4PI",
    "PRESETS",
    "EarthField",
    "HeadImu",
    "ImuSamples",
    "ImuSpec",
    "MagneticDisturbance",
    "SensorSpec",
    "get_imu_spec",
]
