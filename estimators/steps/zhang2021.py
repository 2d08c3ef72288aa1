"""Still / walk recognition and step events from the specific-force norm (Zhang 2021, section 2).

Zhang, Chen & Gao 2021 detect walking in place with a head-worn IMU from the norm of
the specific force, eq (15), ``|f| = sqrt(fx^2 + fy^2 + fz^2)``: the norm is smoothed by a mean
filter, the maximum over a sliding window of N samples is compared with gravity, and eq (16)
reads

    |max(|f|_k .. |f|_{k+N-1}) - g| <  gamma                      => still
    |max(|f|_k .. |f|_{k+N-1}) - g| >= gamma  and  dt_peak <= gamma_t  => walk

where ``dt_peak`` is the interval between neighbouring peaks; each accepted peak is a step event
(the heel strike) at which eq (17) moves the virtual body.

Decisions where the paper is ambiguous or silent (each a field of :class:`GaitParams`):

* **Peaks.** A sample of the smoothed norm is a peak when it is the maximum of the centred window
  of ``N = 2 h + 1`` samples around it (strictly above the h samples before, at least the h after,
  so a flat top gives one peak) and exceeds the baseline by ``gamma``. This is eq (16)'s "max over
  a window of N" evaluated at the one sample where the max sits. We use the signed excess
  ``max - g >= gamma``: ``|max - g|`` would also fire when the whole window lies below
  ``g - gamma`` (free fall), which is no heel strike.
* **gamma_t, the two readings.** Eq (16) says a walk needs ``dt_peak <= gamma_t``; the text beside
  it says the interval must be *longer* than a threshold to reject pseudo-peaks. Both are useful
  and we keep both: ``min_step_interval`` (the text) rejects a peak closer than 1/3.5 s to the
  previous one (nobody steps faster than about 3.5 steps/s; it removes the double bump of a heel
  strike), and ``gamma_t`` (the equation) is the longest interval between neighbouring steps of
  one walking bout. A peak with no neighbour within ``gamma_t`` (an isolated bump: a knock on the
  headset, a sneeze) is not a step. The first peak of a bout is therefore held *pending* and
  reported, together with the second, when the second arrives; a pending peak that finds no
  neighbour within ``gamma_t`` is dropped. A bout of one single step is never counted.
* **Baseline.** Eq (16) compares with g. A consumer accelerometer's zero-g offset (BMI160: up to
  +-40 mg per axis) shifts the static norm by as much as a third of gamma, so by default the
  baseline is the running mean of ``|f|`` (time constant ``baseline_tau``, a cumulative mean until
  that much data has been seen, clamped to ``gravity +- baseline_limit``). Linear acceleration
  averages to zero over a walk, so the mean of the norm is gravity plus the bias along gravity.
  ``baseline_tau = 0`` restores the paper's fixed g.
* **State.** Still/walk per sample follows the accepted steps: walk from the sample where a step is
  confirmed until ``gamma_t`` has passed after the last step's peak (measured on the peak time
  axis, i.e. ``latency`` after the fact); still otherwise, and while the first peak of a bout is
  pending.

Chosen values (at any sample rate; samples = round(seconds * fs), 100 Hz figures in brackets):
mean filter 0.08 s [M = 8], peak window half-width 0.10 s [N = 21 samples, 0.21 s], gamma 0.07 g
(0.686 m/s^2), gamma_t 1.2 s, min_step_interval 1/3.5 s. Why:

* gamma: what separates steps from head gestures is the excess of the smoothed norm over its
  baseline. The simulated head (``vrloco_env.user.motion``; peaks of 1.1-1.5 g when stepping in
  place at 1.2-2.2 steps/s, after Tregillus & Folmer, VR-STEP, CHI 2016) gives at least 0.86 m/s^2
  (0.088 g) for its lightest stepper at 1.2 steps/s; Zhang 2021's head gestures as scripted there
  (serpentine +-40 deg at 0.4 Hz, nod +-30 deg at 0.3 Hz, shake +-25 deg at 0.5 Hz; forehead IMU
  9 cm ahead of and 12 cm above the neck pivot) reach at most 0.51 m/s^2 (0.052 g) with a consumer
  IMU's noise. 0.07 g sits half-way. The gesture envelope below gamma (rigid head, that lever
  arm): yaw at any amplitude up to 40 deg and 1 Hz; pitch nods up to about 30 deg at 0.4 Hz,
  25 deg at 0.5 Hz, 10 deg at 0.7 Hz; roll shakes up to 40 deg at 0.5 Hz, 25 deg at 0.7 Hz,
  15 deg at 1 Hz. Faster or larger nods (the norm excess grows as amplitude x frequency^2: +-30 deg
  at 1 Hz gives 2.7 m/s^2, 0.27 g) *will* read as steps: no threshold on ``|f|`` alone separates
  them from a light heel strike (a gyro-aided test would be needed).
* mean filter 0.08 s: heel-strike pulses at the head last ~0.1-0.2 s, so an 80 ms box loses a few
  percent of their height while averaging out sensor noise and the 5-20 Hz ringing of a phone or
  headset strap; on the Oxford neck-pouch walk it removes most double-peak detections.
* window 0.21 s: shorter than the fastest step interval (0.286 s) so two steps never share a
  window, long enough to take the larger of a heel strike's double bump; it sets the latency.
* gamma_t 1.2 s: 20 % above the slowest in-place step interval we expect (1 step/s).

Latency: a peak is confirmed ``h`` samples after the smoothed norm's peak, and the mean filter
delays the norm by ``(M - 1) / 2`` samples, so the step event comes ``latency = (h + (M - 1)/2) /
fs`` after the heel strike (0.135 s at 100 Hz); the event carries the estimated heel-strike time
(peak sample minus the filter delay). The second step of a bout also releases the first one.

Presets: :meth:`GaitParams.neck_pouch` raises gamma to 0.15 g for a phone hanging in a neck pouch
(the Oxford step-counter recording): the pouch swings on its lanyard and keeps bouncing after the
walker stops (+0.12-0.17 g bumps at ~2 Hz), and over-ground walking hits it with 1.4-1.6 g
heel strikes, so the larger threshold loses nothing there, whereas it would miss the lightest
in-place steps of a head-worn sensor. Measured on that walk (248 true steps, +-0.2 s matching,
``benchmarks/bench_gait.py``): the default finds 258 steps (+4.0 %, F1 0.968; the extra ones
are the phone being put in the pouch and the post-walk swing), ``neck_pouch`` finds 247
(-0.4 %, F1 0.986). These figures are in-sample: gamma was chosen on this same walk. Held out
(two-fold, ``vrloco experiment step-envelope``): gamma chosen from 0.07-0.21 g on either half of
the walk is 0.15 g both ways, and scores TP 244, FP 3, misses 4 (F1 0.986) on the other halves
together. On the simulator's scripted motions (32 users, both IMU presets) the default finds
every step (F1 1.000) and no phantom step.

Offline use: :func:`estimators.steps.offline.detect_steps` runs this detector over one recording
with irregular timestamps.

The per-sample loop is the compiled kernel :data:`estimators.steps._kernel.gait_kernel`, whose
stages the world-vertical detector of :mod:`estimators.steps.nod_robust` shares.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.batching import TakesUsers, stream_rows
from estimators.kernels import param_record, state_records
from estimators.registry import renamed_attributes
from estimators.rotations import GRAVITY
from estimators.stages import GaitChunk
from estimators.steps._kernel import GAIT_STATE, forget_streams, gait_kernel
from estimators.validation import check_in_range, check_numeric

__all__ = ["GaitParams", "StepDetector", "Zhang2021Steps"]


@dataclass(frozen=True)
class GaitParams:
    """Parameters of the still/walk and step detector (see the module docstring for the choices).

    Every field is validated on construction.
    """

    gamma: float = 0.07 * GRAVITY
    """Still/walk threshold (m/s^2): a peak must exceed the baseline by this much (eq 16's gamma).
    Default 0.07 g = 0.686 m/s^2."""
    gamma_t: float = 1.2
    """Longest interval (s) between neighbouring steps of one walking bout (eq 16's gamma_t)."""
    min_step_interval: float = 1.0 / 3.5
    """Shortest interval (s) between two steps; closer peaks are pseudo-peaks (Zhang 2021 text).
    1/3.5 s: humans do not step faster than about 3.5 steps/s."""
    mean_window: float = 0.08
    """Length (s) of the mean filter on the norm (M = round(mean_window * fs) >= 1 samples)."""
    peak_half_window: float = 0.10
    """Half-width (s) of the peak window (h = round(peak_half_window * fs) >= 1; N = 2 h + 1)."""
    baseline_tau: float = 4.0
    """Time constant (s) of the running-mean baseline of |f|; 0 uses ``gravity`` (the paper)."""
    baseline_limit: float = 0.1 * GRAVITY
    """Largest distance (m/s^2) of the baseline from ``gravity``: 0.1 g covers any accelerometer
    offset (BMI160 datasheet: +-40 mg typical zero-g offset)."""
    gravity: float = GRAVITY
    """Gravity (m/s^2), standard gravity by default (:data:`estimators.rotations.GRAVITY`)."""

    def __post_init__(self) -> None:
        check_in_range(self, "gravity", 9.0, 10.5, "m/s^2")
        g = self.gravity
        check_in_range(self, "gamma", 0.0, 3.0 * g, lo_open=True, allowed="in (0, 3 g] m/s^2")
        check_in_range(self, "min_step_interval", 0.0, 2.0, "s")
        check_in_range(
            self,
            "gamma_t",
            self.min_step_interval,
            10.0,
            lo_open=True,
            allowed="in (min_step_interval, 10] s",
        )
        check_in_range(self, "mean_window", 0.0, 1.0, "s", lo_open=True)
        check_in_range(self, "peak_half_window", 0.0, 1.0, "s", lo_open=True)
        check_in_range(self, "baseline_tau", 0.0, 600.0, allowed="in [0, 600] s (0: fixed g)")
        check_in_range(self, "baseline_limit", 0.0, 0.5 * g, allowed="in [0, 0.5 g] m/s^2")

    @classmethod
    def head(cls, **overrides: float) -> GaitParams:
        """The default: a head-worn IMU stepping in place (what the simulator produces)."""
        return cls(**overrides)

    @classmethod
    def neck_pouch(cls, **overrides: float) -> GaitParams:
        """A phone in a neck pouch walking over ground (the Oxford step-counter recording).

        gamma 0.15 g: see the module docstring (pouch swing after stopping reaches 0.17 g). Chosen
        on that recording, so its figure there is in-sample; the module docstring gives the
        two-fold held-out one.
        """
        return cls(**{"gamma": 0.15 * GRAVITY, **overrides})

    def samples(self, fs: float) -> tuple[int, int]:
        """Mean-filter length M and peak half-window h in samples at rate ``fs`` (Hz)."""
        m = max(1, round(self.mean_window * fs))
        h = max(1, round(self.peak_half_window * fs))
        return m, h

    def latency(self, fs: float) -> float:
        """Delay (s) from a heel strike to the sample that confirms it, at rate ``fs`` (Hz)."""
        m, h = self.samples(fs)
        return (h + 0.5 * (m - 1)) / fs

    def build(self, batch_size: int, fs: float) -> Zhang2021Steps:
        """The :class:`Zhang2021Steps` stage with these parameters."""
        return Zhang2021Steps(batch_size, fs, self)


class StepDetector(TakesUsers):
    """Streaming, batched still/walk and step detector (Zhang 2021 eqs (15)-(16)).

    Args:
        batch_size: B, the number of independent streams (users), >= 1.
        fs: sample rate (Hz) of the accelerometer stream, in [10, 2000].
        params: detector parameters; :class:`GaitParams` defaults (head-worn IMU) if None.

    Feed it with :meth:`update` (accelerometer samples) or :meth:`update_norm` (their norms) in
    chunks of any length; chunking does not change the result. Sample k of the stream (counting
    from 0 at construction) is at time ``k / fs`` s, the clock of every reported time.

    Example:
        >>> det = StepDetector(256, 100.0)
        >>> out = det.update(acc)        # acc (256, 10, 3) m/s^2
        >>> out.steps.sum(axis=1)        # steps confirmed in this chunk, per user
    """

    per_user_fields = ("_clock", "_raw", "_sm", "_state")  # clocks, ring buffers, kernel state
    batch_size_field = "batch_size"

    def __init__(self, batch_size: int, fs: float, params: GaitParams | None = None) -> None:
        if not isinstance(batch_size, int | np.integer) or batch_size < 1:
            raise ValueError(f"batch_size must be an integer >= 1, got {batch_size!r}")
        try:
            fs = float(fs)
        except (TypeError, ValueError):
            raise ValueError(f"fs must be a number in [10, 2000] Hz, got {fs!r}") from None
        if not (10.0 <= fs <= 2000.0):
            raise ValueError(f"fs must be in [10, 2000] Hz, got {fs!r}")
        self.params = GaitParams() if params is None else params
        if not isinstance(self.params, GaitParams):
            raise ValueError(f"params must be a GaitParams, got {type(self.params).__name__}")
        self.batch_size = int(batch_size)
        self.fs = fs
        self.m, self.h = self.params.samples(fs)
        self.latency = self.params.latency(fs)
        """Delay (s) from a heel strike to the sample that confirms its step."""
        self.samples_seen = 0
        b = self.batch_size
        self._clock = np.zeros(b, np.int64)  # samples since each stream's reset
        self._prm = param_record(
            self.params, fs=fs, latency=self.latency, base_n=self.params.baseline_tau * fs
        )
        self._raw = np.zeros((b, self.m))
        self._sm = np.zeros((b, 2 * self.h + 1))
        self._state = state_records(GAIT_STATE, b)
        self.reset()

    @property
    def window_samples(self) -> int:
        """Paper's N: the number of samples of the peak window (2 h + 1)."""
        return 2 * self.h + 1

    @property
    def baseline(self) -> NDArray[np.float64]:
        """Current baseline of |f| per stream (m/s^2), (B,)."""
        return self._state["baseline"].copy()

    def reset(self, mask: ArrayLike | None = None) -> None:
        """Forget the past of all streams, or of those where ``mask`` (B,) bool is True.

        Their clocks restart: a reset stream's peak times count from its reset, so a stream
        reset mid-run reports what a new detector would.
        """
        if mask is None:
            sel = np.ones(self.batch_size, dtype=bool)
        else:
            sel = np.asarray(mask)
            if sel.shape != (self.batch_size,) or sel.dtype != np.bool_:
                raise ValueError(
                    f"mask must be a bool array of shape ({self.batch_size},), got "
                    f"{sel.dtype} {sel.shape}"
                )
        forget_streams(self._state, self._clock, sel, self.params.gravity)

    def update(self, acc: ArrayLike) -> GaitChunk:
        """Process accelerometer samples (specific force, m/s^2, any sensor frame).

        Args:
            acc: (B, n, 3) a chunk of n samples, or (B, 3) one sample. NaN samples are replaced
                by the last valid norm (gravity before any).

        Returns:
            A :class:`GaitChunk` over the n samples.
        """
        a = check_numeric(acc, "acc")
        b = self.batch_size
        if a.ndim == 2 and a.shape == (b, 3):
            a = a[:, None, :]
        if a.ndim != 3 or a.shape[0] != b or a.shape[2] != 3:
            raise ValueError(f"acc must have shape ({b}, n, 3) or ({b}, 3), got {a.shape}")
        return self._run(np.sqrt(np.einsum("bni,bni->bn", a, a)))  # a norm: >= 0 or NaN

    def update_norm(self, norm: ArrayLike) -> GaitChunk:
        """Process specific-force norms |f| (m/s^2), (B, n) or (B,) for one sample."""
        x = check_numeric(norm, "norm")
        b = self.batch_size
        if x.ndim == 1 and x.shape == (b,):
            x = x[:, None]
        if x.ndim != 2 or x.shape[0] != b:
            raise ValueError(f"norm must have shape ({b}, n) or ({b},), got {x.shape}")
        if np.any(x < 0.0):
            raise ValueError("norm must be >= 0 m/s^2 (it is a vector norm)")
        return self._run(np.ascontiguousarray(x))

    def _run(self, x: NDArray[np.float64]) -> GaitChunk:
        """The detector over checked norms ``x`` (B, n), C-contiguous."""
        b = self.batch_size
        n = x.shape[1]
        out = (np.zeros((b, n), np.int8), np.zeros((b, n), np.int8), np.full((b, n, 2), np.nan))
        gait_kernel(b)(x, self._clock, self._prm, self._state, self._raw, self._sm, out)
        state, steps, peak_t = out
        t = (self.samples_seen + np.arange(n)) / self.fs
        self.samples_seen += n
        self._clock += n
        return GaitChunk(state=state, steps=steps, peak_time=peak_t, sample_time=t)


class Zhang2021Steps(TakesUsers):
    """Zhang 2021's detector (:class:`StepDetector`, eqs (15)-(16) on ``|f|``) as a step stage of
    :data:`estimators.stages.STEPS`.

    Args:
        batch_size: B, the number of streams (users), >= 1.
        fs: sample rate (Hz) of the IMU, in [10, 2000].
        params: :class:`GaitParams` (defaults if None).

    :meth:`update` takes the stage's ``(acc, gyr, quat)`` and passes ``acc`` alone to
    :meth:`StepDetector.update`: the detector reads only the specific-force norm, so its output is
    that of :class:`StepDetector` bit for bit.
    """

    per_user_parts = ("detector",)
    batch_size_field = "batch_size"

    def __init__(self, batch_size: int, fs: float, params: GaitParams | None = None) -> None:
        self.detector = StepDetector(batch_size, fs, params)
        self.params = self.detector.params
        self.batch_size = self.detector.batch_size
        self.fs = self.detector.fs
        self.latency = self.detector.latency
        """Delay (s) from a heel strike to the sample that confirms its step."""
        self.report_delay_s = self.params.gamma_t + self.latency
        """Longest delay (s) from a heel strike to its report: a bout's first step is held
        until the second, at most ``gamma_t`` later."""

    @property
    def samples_seen(self) -> int:
        """Samples consumed since construction (sample k is at time k / fs s)."""
        return self.detector.samples_seen

    def reset(self, rows: ArrayLike | None = None) -> None:
        """Forget the streams ``rows`` (indices, a (B,) bool mask, or None: all); their clocks
        restart (see :meth:`StepDetector.reset`)."""
        mask = np.zeros(self.batch_size, dtype=bool)
        mask[stream_rows(rows, self.batch_size, "rows")] = True
        self.detector.reset(mask)

    def update(self, acc: ArrayLike, gyr: ArrayLike, quat: ArrayLike) -> GaitChunk:
        """Consume (B, N, 3) specific force (m/s^2); ``gyr`` and ``quat`` are not read."""
        a = check_numeric(acc, "acc")
        if a.ndim != 3:
            raise ValueError(f"acc must have shape ({self.batch_size}, N, 3), got {a.shape}")
        return self.detector.update(a)


#: The earlier name, importable for one release with a deprecation warning.
__getattr__ = renamed_attributes(globals(), {"Seed000Steps": "Zhang2021Steps"})
