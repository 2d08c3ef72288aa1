"""Human variability on top of any scripted user: reaction delay, turn overshoot, cadence jitter.

:class:`HumanVariability` wraps a policy (``reset``/``act``, :class:`agents.scripted.Policy`)
and makes it behave less like a machine:

* **Reaction delay.** The wrapped policy sees the observation of ``k`` control steps ago, ``k =
  round(delay / dt)`` with the delay drawn per user and episode from
  ``N(reaction_delay_s, reaction_delay_sd_s)`` clipped to ``[0, max_delay_s]``. Default 0.25 s
  +- 0.05 s: the simple visual reaction time of adults is about 0.2-0.25 s (Welford, *Reaction
  Times*, 1980; Woods et al., *Front. Hum. Neurosci.* 9:131, 2015, report ~0.24 s on average);
  a user reacting to a VR scene while stepping in place is at the slow end of that range.
  Before ``k`` observations exist the policy sees the first one of the episode.
* **Turn overshoot.** A *turn bout* is a run of control steps in which the wrapped policy turns
  one way (``|turn| >= turn_threshold``, one sign). When a bout whose net command
  ``sum(turn)`` (action x control steps; times ``max_turn_rate * dt`` it is the angle) is at
  least ``min_bout`` ends, the user keeps turning the same way for an extra ``f * |sum(turn)|``,
  at ``overshoot_rate`` per control step, with ``f`` drawn per bout from ``N(overshoot,
  overshoot_sd)`` clipped at 0 — the ballistic end of a whole-body turn that a closed-loop
  policy then corrects. Default 0.1 +- 0.05 (an engineering choice: undershoot and overshoot of
  some 10 % of the turned angle are typical of whole-body rotations without vision of the
  physical room, e.g. Bakker, Werkhoven & Passenier, *Presence* 8(1), 1999; we model only the
  overshoot, the ballistic part). While the overshoot lasts it replaces the policy's turn.
* **Cadence.** A walking user's walk action (``> 0``) is scaled by ``1 + bias + jitter``: the
  bias is drawn per user and episode from ``N(0, cadence_bias_sd)`` (people step at their own
  pace) and the jitter per control step from ``N(0, cadence_jitter_sd)`` (step-to-step
  variation; stride-time variability of healthy adults is 2-3 % CV, Hausdorff, *J.
  NeuroEngineering Rehabil.* 2:19, 2005, and stepping in place to a VR scene is less regular,
  so 5 %). The result stays in ``[0.01, 1]``: jitter never stops a walking user nor makes a
  standing one walk.

A user population (:mod:`vrloco_env.user.population`) carries its own values of these parameters
(:meth:`VariabilityParams.from_population`; the ``+<population>`` policy suffix of
:mod:`agents.benchmark.policies`): ``human`` is the defaults above.

Randomness: every draw goes through :class:`vrloco_env.batch_rng.BatchRng`, row i from user
i's generator, with a fixed number of draws per user and step (two normals per ``act``,
two per reset), so a batch of B users reproduces B single runs bit for bit and the same
generator gives the same actions.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from agents.scripted import Policy
from estimators.batching import TakesUsers
from estimators.validation import check_in_range
from vrloco_env.batch_rng import BatchRng

__all__ = ["HumanVariability", "VariabilityParams"]


@dataclass(frozen=True)
class VariabilityParams:
    """How a simulated human deviates from the scripted user (see the module docstring).

    Attributes:
        reaction_delay_s: mean reaction delay (s).
        reaction_delay_sd_s: spread of the delay between users/episodes (s).
        max_delay_s: the delay is clipped to [0, max_delay_s] (s).
        overshoot: mean extra turn after a turn bout, as a fraction of the bout's turn.
        overshoot_sd: spread of that fraction between bouts.
        overshoot_rate: turn action while overshooting (in [0, 1], the action's units).
        turn_threshold: smallest |turn| action that counts as turning.
        min_bout: smallest net turn command of a bout that overshoots (action x steps; 0.5 is
            6 deg at 120 deg/s and 10 Hz).
        cadence_bias_sd: spread of a user's relative cadence preference.
        cadence_jitter_sd: relative cadence jitter per control step.
        dt_s: control period (s), 0.1 at the env's 10 Hz.
    """

    reaction_delay_s: float = 0.25
    reaction_delay_sd_s: float = 0.05
    max_delay_s: float = 1.0
    overshoot: float = 0.1
    overshoot_sd: float = 0.05
    overshoot_rate: float = 0.5
    turn_threshold: float = 0.05
    min_bout: float = 0.5
    cadence_bias_sd: float = 0.1
    cadence_jitter_sd: float = 0.05
    dt_s: float = 0.1

    def __post_init__(self) -> None:
        check_in_range(self, "max_delay_s", 0.0, 10.0, "s")
        check_in_range(self, "reaction_delay_s", 0.0, self.max_delay_s, "s (<= max_delay_s)")
        check_in_range(self, "reaction_delay_sd_s", 0.0, 10.0, "s")
        check_in_range(self, "overshoot", 0.0, 2.0)
        check_in_range(self, "overshoot_sd", 0.0, 2.0)
        check_in_range(self, "overshoot_rate", 0.01, 1.0)
        check_in_range(self, "turn_threshold", 0.0, 1.0)
        check_in_range(self, "min_bout", 0.0, 100.0)
        check_in_range(self, "cadence_bias_sd", 0.0, 1.0)
        check_in_range(self, "cadence_jitter_sd", 0.0, 1.0)
        check_in_range(self, "dt_s", 1e-3, 10.0, "s")

    @classmethod
    def from_population(cls, population: Any, **overrides: Any) -> VariabilityParams:
        """The agent-side variability of a user population
        (:mod:`vrloco_env.user.population`: a registered name or a ``Population``); ``human``
        gives the defaults. ``overrides``: further fields (``dt_s``)."""
        from vrloco_env.user.population import get_population

        p = get_population(population)
        names = (
            "reaction_delay_s",
            "reaction_delay_sd_s",
            "overshoot",
            "overshoot_sd",
            "cadence_bias_sd",
            "cadence_jitter_sd",
        )
        return cls(**{**{n: getattr(p, n) for n in names}, **overrides})

    @property
    def max_delay_steps(self) -> int:
        """The longest delay in control steps."""
        return round(self.max_delay_s / self.dt_s)


def _as_batch_rng(rng: Any) -> BatchRng:
    """A BatchRng from a Generator (one user), a sequence of Generators, or a BatchRng."""
    if isinstance(rng, BatchRng):
        return rng
    if isinstance(rng, np.random.Generator):
        return BatchRng([rng])
    if isinstance(rng, Sequence) and rng and all(isinstance(g, np.random.Generator) for g in rng):
        return BatchRng(list(rng))
    raise ValueError(
        "rng must be a numpy.random.Generator (one user), a sequence of them (one per user) or "
        f"a BatchRng, got {type(rng).__name__}"
    )


class HumanVariability(TakesUsers):
    """Reaction delay, turn overshoot and cadence variation around any policy.

    A batch drops users with ``take_users(rows)`` (:class:`~estimators.batching.TakesUsers`),
    which the wrapped policy must have too: each kept user goes on with its own delay, history,
    bout, cadence bias and random stream, as in the whole batch.

    Args:
        policy: the wrapped user (``reset(rng, rows)``, ``act(obs)``).
        params: the variability model (a population's: :meth:`VariabilityParams.from_population`).
        population: the population's name, for the wrapper's ``name`` (``goal_seeker+human``).

    Example:
        >>> user = HumanVariability(GoalSeeker())          # doctest: +SKIP
        >>> user.reset(np.random.default_rng(7))            # doctest: +SKIP
        >>> action = user.act(obs)                          # doctest: +SKIP
    """

    # each user's episode draws, history of observations and turn bout
    per_user_fields = ("_bias", "_bout", "_delay", "_fresh", "_hist", "_over")
    per_user_parts = ("_rng", "policy")
    batch_size_field = "_b"

    @property
    def batched(self) -> bool:
        """Batches of users when the wrapped policy takes them."""
        return bool(getattr(self.policy, "batched", False))

    def set_active(self, mask: Any) -> None:
        """Passed on to the wrapped policy where it has it (see
        :meth:`agents.scripted.ScriptedPolicy.set_active`)."""
        if callable(getattr(self.policy, "set_active", None)):
            self.policy.set_active(mask)

    def __init__(
        self, policy: Policy, params: VariabilityParams | None = None, population: str = "human"
    ) -> None:
        methods = (getattr(policy, "act", None), getattr(policy, "reset", None))
        if not all(callable(m) for m in methods):
            raise TypeError("policy must have reset(rng, rows) and act(obs) methods")
        self.policy = policy
        self.params = params or VariabilityParams()
        if not isinstance(self.params, VariabilityParams):
            raise TypeError(f"params must be a VariabilityParams, got {type(params).__name__}")
        if not isinstance(population, str) or not population:
            raise ValueError(f"population={population!r}: must be a non-empty name")
        self.name = f"{getattr(policy, 'name', type(policy).__name__)}+{population}"
        self._rng: BatchRng | None = None
        self._b = 0

    # ---------------------------------------------------------------- episodes
    def reset(self, rng: Any = None, rows: ArrayLike | None = None) -> None:
        """Start new episodes and draw each user's delay and cadence bias.

        Args:
            rng: a ``numpy.random.Generator`` (one user), a sequence of them (one per user, or
                one per reset row when ``rows`` is given) or a ``BatchRng``. Required: all of
                this wrapper's randomness comes from it.
            rows: reset only these users of the batch (a vector env's autoreset); None: all.

        Raises:
            ValueError: no generator, or the wrong number of them.
        """
        if rng is None:
            raise ValueError(
                "HumanVariability.reset needs rng (a numpy.random.Generator or one "
                "per user): all its randomness comes from there"
            )
        if rows is None:
            self._rng = _as_batch_rng(rng)
            self._b = self._rng.batch_size
            self._alloc(self._b)
            self._draw_episode(np.arange(self._b))
            self.policy.reset(rng, None)
            return
        if self._rng is None:
            raise ValueError("reset(rng) for all users must come before reset(rng, rows)")
        r = np.asarray(rows, dtype=np.intp).ravel()
        sub = _as_batch_rng(rng)
        if sub.batch_size != r.size:
            raise ValueError(
                f"rng must hold one generator per reset row ({r.size}), got {sub.batch_size}"
            )
        for k, i in enumerate(r):
            self._rng.reseed(int(i), sub.generators[k])
        self._draw_episode(r)
        self.policy.reset(rng, r)

    def take_users(self, rows: ArrayLike) -> None:
        """Keep the users ``rows`` (distinct indices into the batch, in their new order), here
        and in the wrapped policy.

        Raises:
            RuntimeError: ``reset`` has not been called.
            TypeError: the wrapped policy has no ``take_users`` (nothing is changed).
        """
        if self._rng is None:
            raise RuntimeError("reset(rng) must be called before take_users()")
        super().take_users(np.asarray(rows, dtype=np.intp))

    def _alloc(self, b: int) -> None:
        h = self.params.max_delay_steps + 1
        self._hist: NDArray[np.float64] | None = None  # (B, h, n), newest first
        self._hist_len = h
        self._fresh = np.ones(b, bool)
        self._delay = np.zeros(b, np.intp)
        self._bias = np.zeros(b)
        self._bout = np.zeros(b)  # net turn command of the current bout (signed)
        self._over = np.zeros(b)  # overshoot still to do (signed, action x steps)

    def _draw_episode(self, rows: NDArray[np.intp]) -> None:
        p = self.params
        assert self._rng is not None
        z = self._rng.normal((2,), rows=rows)
        delay = np.clip(p.reaction_delay_s + p.reaction_delay_sd_s * z[:, 0], 0.0, p.max_delay_s)
        self._delay[rows] = np.rint(delay / p.dt_s).astype(np.intp)
        self._bias[rows] = p.cadence_bias_sd * z[:, 1]
        self._fresh[rows] = True
        self._bout[rows] = 0.0
        self._over[rows] = 0.0

    @property
    def delay_steps(self) -> NDArray[np.intp]:
        """Each user's reaction delay in this episode (control steps)."""
        return self._delay.copy()

    @property
    def cadence_bias(self) -> NDArray[np.float64]:
        """Each user's relative cadence bias in this episode."""
        return self._bias.copy()

    # ---------------------------------------------------------------- acting
    def act(self, obs: ArrayLike) -> NDArray[np.float32]:
        """Actions ``(5,)`` for one observation ``(n,)`` or ``(B, 5)`` for ``(B, n)``: the
        wrapped policy acts on what the user perceives (:meth:`perceive`) and the body carries
        its action out (:meth:`respond`).

        Raises:
            RuntimeError: ``reset`` has not been called.
            ValueError: the batch size differs from the number of generators given to reset.
        """
        seen = self.perceive(obs)
        single = np.ndim(obs) == 1
        inner = self.policy.act(seen[0] if single else seen)
        out = self.respond(inner)
        return out[0] if single else out

    def perceive(self, obs: ArrayLike) -> NDArray[np.float64]:
        """What each user perceives of ``obs`` ((n,) or (B, n)) this control step: the
        observation of its reaction delay ago, (B, n). Call once per step, then :meth:`respond`.

        Raises:
            RuntimeError: ``reset`` has not been called.
            ValueError: the batch size differs from the number of generators given to reset.
        """
        if self._rng is None:
            raise RuntimeError("reset(rng) must be called before act()")
        o = np.asarray(obs, dtype=np.float64)
        o2 = o[None] if o.ndim == 1 else o
        if o2.ndim != 2 or o2.shape[0] != self._b:
            raise ValueError(
                f"obs must hold {self._b} row(s) (one per generator given to "
                f"reset), got shape {np.shape(obs)}"
            )
        b = self._b
        # reaction delay: a history of observations, newest first
        if self._hist is None or self._hist.shape[2] != o2.shape[1]:
            self._hist = np.repeat(o2[:, None], self._hist_len, axis=1)
            self._fresh[:] = False
        self._hist[:, 1:] = self._hist[:, :-1].copy()
        self._hist[:, 0] = o2
        if np.any(self._fresh):  # a new episode: the past is its first observation
            self._hist[self._fresh] = o2[self._fresh][:, None]
            self._fresh[:] = False
        return self._hist[np.arange(b), self._delay]

    def respond(self, action: ArrayLike) -> NDArray[np.float32]:
        """The actions (B, 5) the users' bodies carry out for the policy's ``action`` ((5,) or
        (B, 5)): turn overshoot after a bout and the cadence's bias and jitter."""
        if self._rng is None:
            raise RuntimeError("reset(rng) must be called before act()")
        p = self.params
        a = np.asarray(action, dtype=np.float64).reshape(self._b, -1).copy()
        z = self._rng.normal((2,))  # the same two draws per user and step, used or not

        # turn overshoot after a bout
        turn = a[:, 1]
        sign = np.sign(turn) * (np.abs(turn) >= p.turn_threshold)
        bout_sign = np.sign(self._bout)
        ended = (bout_sign != 0) & (sign != bout_sign)
        frac = np.maximum(p.overshoot + p.overshoot_sd * z[:, 0], 0.0)
        starts = ended & (np.abs(self._bout) >= p.min_bout) & (self._over == 0.0)
        self._over = np.where(starts, frac * self._bout, self._over)
        self._bout = np.where(ended, 0.0, self._bout) + np.where(sign != 0, turn, 0.0)
        over = self._over != 0.0
        step = np.sign(self._over) * np.minimum(np.abs(self._over), p.overshoot_rate)
        a[:, 1] = np.where(over, step, turn)
        self._over = np.where(over, self._over - step, 0.0)
        self._over[np.abs(self._over) < 1e-12] = 0.0
        self._bout = np.where(over, 0.0, self._bout)  # an overshoot is not a new bout

        # cadence bias and jitter of a walking user
        walk = a[:, 0]
        scaled = np.clip(walk * (1.0 + self._bias + p.cadence_jitter_sd * z[:, 1]), 0.01, 1.0)
        a[:, 0] = np.where(walk > 0.0, scaled, walk)
        return np.clip(a, -1.0, 1.0).astype(np.float32)
