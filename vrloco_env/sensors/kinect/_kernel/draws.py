"""The Kinect v2 kernel's random draws from standard normals
(:mod:`vrloco_env.sensors.kinect._kernel`, "four devices" in its docstring): a normal's uniform
(:func:`uniform`), the splitting of one uniform into several decisions (:func:`bernoulli_split`,
:func:`categorical_split`, :func:`geometric_split`), compiled (``numba.njit(cache=True)``), and
the ARMA(1, 1) form of white + AR(1) noise (:func:`arma_parameters`).
"""

from __future__ import annotations

import math

import numba

__all__ = [
    "arma_parameters",
    "bernoulli_split",
    "categorical_split",
    "geometric_split",
    "uniform",
]

_BELOW_ONE = 1.0 - 2.0**-53
_SQRT_HALF = math.sqrt(0.5)


def arma_parameters(white_fraction: float, rho: float) -> tuple[float, float]:
    """Innovation scale ``s`` and MA coefficient ``theta`` of white + AR(1) noise as ARMA(1, 1).

    The unit-variance process ``x_t = sqrt(wf) w_t + sqrt(1 - wf) a_t`` (w white, a AR(1) with
    coefficient rho) satisfies ``x_t - rho x_{t-1} = m_t``, an MA(1) with variance
    ``g0 = wf (1 + rho^2) + (1 - wf)(1 - rho^2)`` and lag-1 covariance ``g1 = -rho wf``, so
    ``m_t = s (e_t + theta e_{t-1})`` with ``s^2 (1 + theta^2) = g0``, ``s^2 theta = g1`` and the
    invertible root ``|theta| <= 1``.

    Args:
        white_fraction: wf in [0, 1].
        rho: AR(1) coefficient per step in [0, 1).

    Returns:
        ``(s, theta)``; the stationary state has ``var(y) = 1`` and ``cov(y_t, e_t) = s``.
    """
    g0 = white_fraction * (1.0 + rho * rho) + (1.0 - white_fraction) * (1.0 - rho * rho)
    g1 = -rho * white_fraction
    r = g1 / g0
    if r == 0.0:
        return math.sqrt(g0), 0.0
    theta = (1.0 - math.sqrt(max(1.0 - 4.0 * r * r, 0.0))) / (2.0 * r)
    return math.sqrt(g1 / theta), theta


@numba.njit(cache=True)
def uniform(z: float) -> float:
    """Uniform in [0, 1) from a standard normal: its CDF, ndtr(z), kept below 1."""
    return min(0.5 * math.erfc(-z * _SQRT_HALF), _BELOW_ONE)


@numba.njit(cache=True)
def bernoulli_split(u: float, p: float) -> tuple[bool, float]:
    """A Bernoulli(p) trial ``u < p`` on a uniform, and the uniform rescaled for the next draw.

    Given the outcome, ``u`` is uniform on [0, p) or [p, 1); rescaled to [0, 1) it is independent
    of the outcome, so a chain of calls on one uniform gives independent trials.
    """
    if u < p:
        return True, min(u / p, _BELOW_ONE)
    return False, min((u - p) / (1.0 - p), _BELOW_ONE)


@numba.njit(cache=True)
def categorical_split(u: float, n: int) -> tuple[int, float]:
    """A uniform choice among ``n`` values, floor(u n), and the uniform rescaled (fraction)."""
    x = u * n
    k = min(int(x), n - 1)
    return k, min(max(x - k, 0.0), _BELOW_ONE)


@numba.njit(cache=True)
def geometric_split(u: float, q: float) -> tuple[int, float]:
    """A length L >= 1 with P(L > k) = q^k, and the uniform rescaled for the next draw.

    L = max(1, ceil(log(1 - u) / log(q))): an exponential length of mean -1 / log(q) frames
    rounded up, as the numpy model drew it. Given L, ``u`` is uniform on
    [1 - q^(L-1), 1 - q^L); rescaled to [0, 1) it is independent of L.
    """
    length = max(1, math.ceil(math.log1p(-u) / math.log(q)))
    top = q ** (length - 1)  # P(L >= length)
    return length, min(max((u - (1.0 - top)) / (top * (1.0 - q)), 0.0), _BELOW_ONE)
