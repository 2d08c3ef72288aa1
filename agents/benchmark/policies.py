"""Simulated users for the benchmark, by name: scripted, learned, or your own.

A policy spec is one of

* a scripted user of :data:`agents.scripted.POLICIES` (``goal_seeker``, ``avoid_manoeuvre``,
  ``reactive_avoider``);
* ``"package.module:attr"`` or ``"path/to/file.py:attr"`` naming a class or factory called as
  ``factory(env)`` that returns an object with the :class:`~agents.scripted.Policy` protocol
  (``reset(rng=None, rows=None)``, ``act(obs) -> action``);
* the path of a stable-baselines3 PPO model (``.zip``), played with its deterministic policy;
* ``ppo``: the learned user shipped for the env's task (:mod:`agents.learned.users`);
  ``ppo@STEPS``: that user adapted to the env's cell by ``STEPS`` more training steps
  (:func:`agents.learned.adapt.adapted_user`, cached; ``ppo@0`` is ``ppo``), and
  ``ppo@STEPS:SEED`` the same with the fine-tuning's random seed ``SEED`` (0 without one), to
  see how much an adapted user owes to the seed it was tuned with;

each optionally followed by ``+<population>`` for the agent-side variability of a user population
(:mod:`vrloco_env.user.population`) through :class:`agents.benchmark.variability.HumanVariability`
(reaction delay, turn overshoot, cadence bias and jitter): ``+human`` as it always was,
``+typical``, ``+gaze_scanners``, ``+nodders``; ``+idealised`` leaves the policy as it is. The
population's head behaviour is the env's (``gym.make(..., population="typical")``); give both
for the whole population.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from agents.benchmark.variability import HumanVariability, VariabilityParams
from agents.learned.models import read_fields
from agents.learned.residual import combine, with_scripted_action
from agents.scripted import POLICIES, ObservationLayout, make_policy, params_from_env
from estimators.batching import TakesUsers
from vrloco_env.user.population import POPULATIONS
from vrloco_env.wrappers import StackedFrames

__all__ = [
    "HUMAN_SUFFIX",
    "SHIPPED",
    "LearnedPolicy",
    "adapt_seed",
    "adapt_steps",
    "adaptation",
    "adapted_path",
    "build_policy",
    "check_policy",
    "env_population",
    "load_ppo",
]

HUMAN_SUFFIX = "+human"
#: The policy spec of the shipped learned user of each task.
SHIPPED = "ppo"


def _split(spec: str) -> tuple[str, str | None]:
    """The policy's base spec and its population suffix's name (None without one)."""
    if not isinstance(spec, str) or not spec:
        raise ValueError(f"policy={spec!r}: must be a non-empty string")
    base, sep, suffix = spec.rpartition("+")
    if not sep or not base or not suffix.isidentifier():  # no suffix ("my+model.zip")
        return spec, None
    if suffix not in POPULATIONS:
        raise ValueError(
            f"policy={spec!r}: unknown population {suffix!r} after '+'; valid names: "
            f"{', '.join(POPULATIONS)}"
        )
    return base, suffix


def env_population(spec: str) -> str | None:
    """The env-side population of a policy spec: its ``+<population>`` suffix where that
    population acts on the simulated body (gaze, nods, bob: ``Population.moves_head``), else
    None — the env of a ``+human`` or ``+idealised`` user is the default env, bit for bit."""
    _, population = _split(spec)
    if population is None or not POPULATIONS[population].moves_head:
        return None
    return population


def check_policy(spec: str) -> str:
    """``spec`` if it names a policy (see the module docstring), else a ValueError saying what
    is allowed. Checks what can be checked without an env: a scripted name, an existing model
    file, an importable ``module:attr``."""
    base, _ = _split(spec)
    if base in POLICIES or base == SHIPPED:
        return spec
    if base.startswith(SHIPPED + "@"):
        adaptation(spec)
        return spec
    if base.endswith(".zip"):
        if not Path(base).is_file():
            raise ValueError(f"policy={spec!r}: no such model file {base!r}")
        return spec
    if ":" in base:
        from estimators.registry import load_attr

        try:
            obj = load_attr(base, "policy")
        except ValueError as err:
            raise ValueError(str(err)) from None
        if not callable(obj):
            raise ValueError(
                f"policy={spec!r} names a {type(obj).__name__}, not a class or factory"
            )
        return spec
    raise POLICIES.unknown(
        spec,
        also=f"{SHIPPED!r} (the task's shipped learned user), a stable-baselines3 model "
        "(.zip) or 'package.module:attr', optionally with "
        f"'+<population>' ({', '.join(POPULATIONS)}; e.g. goal_seeker{HUMAN_SUFFIX})",
    )


class LearnedPolicy(TakesUsers):
    """A saved stable-baselines3 PPO model as a policy (deterministic actions).

    The model reads the observation fields it was trained on, by name
    (:func:`agents.learned.models.observation_columns`: a field it does not know, such as a
    population's ``head_on_torso``, is left unread; one it knows that changed is an error). The
    model sees the env as it was trained to (``model.vrloco_policy``,
    :func:`agents.learned.models.model_policy`): with a frame stack, each user's last k observations
    side by side (:class:`~vrloco_env.wrappers.StackedFrames`, started from the episode's first
    observation at every ``reset``); a recurrent model (sb3-contrib's ``RecurrentPPO``) carries
    each user's LSTM state from step to step, started afresh at ``reset``. A model that corrects
    a scripted user (``vrloco train --residual-on``, :mod:`agents.learned.residual`) plays beside
    that scripted user, built for ``env``: the model sees its action as one more field and the
    action played is the scripted one plus the model's correction.

    Args:
        path: the model's ``.zip``.
        env: the env it will play; a model that ``vrloco train`` saved carries its task, which
            must be the env's (unless ``allow_mismatch``), and its observation size must be the
            env's (times its frame stack).
        allow_mismatch: play a model on another task than its own (``vrloco evaluate
            --allow-mismatch``); the observation and action sizes must still fit.
    """

    batched = True  # act() takes (B, n) rows, one at a time (see act)
    per_user_fields = ("_fresh", "_state")
    per_user_parts = ("_frames", "_teacher")

    def __init__(self, path: str | Path, env: Any, allow_mismatch: bool = False) -> None:
        from agents.learned.models import model_policy, observation_columns

        self.path = Path(path)
        self.name = f"ppo:{self.path.name}"
        self.model = _load_ppo(self.path)
        settings = getattr(self.model, "vrloco_env", None)
        task = getattr(env.unwrapped, "task_name", None)
        if (
            isinstance(settings, dict)
            and task is not None
            and settings.get("task") != task
            and not allow_mismatch
        ):
            raise ValueError(
                f"policy {str(self.path)!r} was trained on task {settings.get('task')!r}, not "
                f"{task!r}"
            )
        spec = getattr(env.unwrapped, "observation_spec", None)
        seen = model_policy(self.model)
        self.frame_stack, self.recurrent = seen["frame_stack"], seen["recurrent"]
        self._teacher = None  # the scripted user whose actions the model corrects
        if seen["residual_on"] is not None:
            self._teacher = _scripted_user(self.path, seen["residual_on"], env)
            if spec is not None:
                spec = with_scripted_action(spec, seen["residual_on"])
        saved = getattr(self.model, "vrloco_observation", None)
        try:
            self._columns = None if spec is None else observation_columns(saved, spec)
        except ValueError as err:
            raise ValueError(
                f"policy {str(self.path)!r} is stale: {err}; train it again on this "
                f"version (vrloco train){_trained_on(self.model)}"
            ) from None
        size = env.unwrapped.observation_space.shape[-1]
        if self._columns is not None:
            size = self._columns.size  # the fields it knows, by name (others left unread)
        want = (size * self.frame_stack,)
        have = self.model.observation_space.shape
        if have != want:
            stack = f" ({self.frame_stack} frames of {size})" if self.frame_stack > 1 else ""
            raise ValueError(
                f"policy {str(self.path)!r} takes observations of shape {have}, the env gives "
                f"{want}{stack}{_trained_on(self.model)}"
            )
        want = env.unwrapped.action_space.shape[-1:]
        have = getattr(self.model.action_space, "shape", None)
        if have != want:
            raise ValueError(
                f"policy {str(self.path)!r} gives actions of shape {have}, the env takes {want}"
            )
        self._size = size
        self._frames: StackedFrames | None = None  # each user's last frames
        self._fresh: NDArray[np.bool_] | None = None  # (B,): the user's episode starts now
        self._state: NDArray[np.float32] | None = None  # (B, 2, layers, 1, hidden): h, c

    def reset(self, rng: Any = None, rows: ArrayLike | None = None) -> None:
        """Start the episodes of ``rows`` (None: every user; the batch size is then that of
        ``rng`` where it is a list, else of the next ``act``): their frames restart from the
        next observation, their recurrent state from zero."""
        if self._teacher is not None:
            self._teacher.reset(rows=rows)
        if rows is None:
            n = len(rng) if isinstance(rng, list | tuple) else None
            self._frames = self._state = None
            self._fresh = None if n is None else np.ones(n, bool)
            return
        if self._fresh is not None:
            self._fresh[np.asarray(rows, dtype=np.intp)] = True

    def act(self, obs: ArrayLike) -> NDArray[np.float32]:
        """Deterministic actions for ``obs``, (obs,) or (B, obs). A batch is evaluated one row
        at a time: torch's matrix kernels round differently for different batch sizes, and an
        episode must not depend on how many users it was batched with."""
        x = np.asarray(obs, dtype=np.float32)
        rows = x.reshape(1, -1) if x.ndim == 1 else x
        scripted = None
        if self._teacher is not None:  # what the scripted user does, which the model corrects
            scripted = np.asarray(self._teacher.act(rows), np.float32).reshape(len(rows), -1)
            rows = np.concatenate([rows, scripted], axis=1)
        rows = read_fields(rows, self._columns)  # the fields it knows, by name
        n = rows.shape[0]
        if self._fresh is None or self._fresh.shape[0] != n:
            self._fresh, self._frames, self._state = np.ones(n, bool), None, None
        fresh = self._fresh
        if self.frame_stack > 1:
            if self._frames is None:
                self._frames = StackedFrames(self.frame_stack, self._size)
                self._frames.start(rows)
            else:
                self._frames.push(rows)
                if fresh.any():  # an episode's first frame, repeated
                    self._frames.start(rows, np.flatnonzero(fresh))
            seen = self._frames.stacked()
        else:
            seen = rows
        if self.recurrent:
            actions = self._act_recurrent(seen, fresh)
        else:
            actions = self._act_rows(seen)
        self._fresh = np.zeros(n, bool)
        out = np.asarray(actions, dtype=np.float32).reshape(n, -1)
        if scripted is not None:
            out = combine(scripted, out)
        return out[0] if x.ndim == 1 else out

    def _act_rows(self, seen: NDArray[np.float32]) -> NDArray[np.float32]:
        """Each row's deterministic action, from that row alone: the actor's mean clipped to the
        action space, what ``model.predict(row, deterministic=True)`` returns to the last bit
        (the tests check it), without the conversions and checks it makes on every call."""
        import torch

        policy, space = self.model.policy, self.model.action_space
        if getattr(policy, "squash_output", False):  # predict un-squashes: leave it to predict
            return np.asarray([self.model.predict(row, deterministic=True)[0] for row in seen])
        out = np.empty((len(seen), space.shape[0]), np.float32)
        policy.set_training_mode(False)
        with torch.inference_mode():
            for i, row in enumerate(seen):
                features = policy.extract_features(
                    torch.as_tensor(row[None]), policy.pi_features_extractor
                )
                out[i] = policy.action_net(policy.mlp_extractor.forward_actor(features))[0].numpy()
        return np.clip(out, space.low, space.high)

    def _act_recurrent(self, seen: NDArray[np.float32], fresh: NDArray[np.bool_]) -> list:
        """Each row's action and new LSTM state, from its own state (zero where ``fresh``)."""
        actions = []
        states = []
        for i, row in enumerate(seen):
            state = None if self._state is None else (self._state[i, 0], self._state[i, 1])
            action, (h, c) = self.model.predict(
                row[None], state=state, episode_start=fresh[i : i + 1], deterministic=True
            )
            actions.append(action[0])
            states.append(np.stack([h, c]))
        self._state = np.asarray(states, dtype=np.float32)
        return actions


def _scripted_user(path: Path, name: str, env: Any) -> Any:
    """The scripted user ``name`` a model at ``path`` corrects, built for ``env``, or a
    ValueError naming the model and the scripted users there are."""
    if name not in POLICIES:
        raise ValueError(
            f"policy {str(path)!r} corrects the scripted user {name!r}, which is not "
            f"registered; scripted users: {', '.join(sorted(POLICIES))}"
        )
    return _scripted(name, env)


def _scripted(name: str, env: Any) -> Any:
    """The registered scripted user ``name`` built for ``env``: its observation layout and its
    body (:func:`agents.scripted.params_from_env`)."""
    return make_policy(name, ObservationLayout.from_env(env), params_from_env(env))


def _trained_on(model: Any) -> str:
    """``"; it was trained on <cell>"`` for a model that carries its cell, else ``""``."""
    cell = getattr(model, "vrloco_cell", None)
    if not isinstance(cell, dict):
        return ""
    return "; it was trained on " + ", ".join(f"{k} {v!r}" for k, v in cell.items())


def load_ppo(path: str | Path) -> Any:
    """The stable-baselines3 PPO model saved at ``path`` (its ``.zip``): sb3-contrib's
    ``RecurrentPPO`` where its policy is a recurrent one (``vrloco train --recurrent``).

    Raises:
        ValueError: one line naming the file: no such file, not a zip file, a zip that is no
            stable-baselines3 model (no ``data`` and ``policy.pth`` in it), or one that PPO
            cannot load (another algorithm's, or damaged).
    """
    import zipfile

    from stable_baselines3 import PPO

    path = Path(path)
    if not path.is_file():
        hint = (
            f"; did you mean {str(path) + '.zip'!r}?" if Path(str(path) + ".zip").is_file() else ""
        )
        raise ValueError(f"{str(path)!r}: no such model file{hint}")
    try:
        with zipfile.ZipFile(path) as z:
            names = set(z.namelist())
            data = z.read("data") if "data" in names else b""
    except (zipfile.BadZipFile, OSError) as err:
        raise ValueError(f"{str(path)!r} is not a saved model: not a zip file ({err})") from None
    missing = [n for n in ("data", "policy.pth") if n not in names]
    if missing:
        raise ValueError(
            f"{str(path)!r} is not a saved stable-baselines3 model: the zip holds no "
            f"{' and no '.join(missing)} (a model saved by vrloco train or model.save() has both)"
        )
    algorithm: Any = PPO
    if _recurrent_policy(data):
        try:
            from sb3_contrib import RecurrentPPO
        except ImportError:
            raise ValueError(
                f"{str(path)!r} is a recurrent model (RecurrentPPO): loading it "
                "needs sb3-contrib (pip install sb3-contrib)"
            ) from None
        algorithm = RecurrentPPO
    try:
        return algorithm.load(path)
    except Exception as err:  # another algorithm's model, or a damaged one: one line
        cause = str(err).strip().splitlines()[0] if str(err).strip() else ""
        raise ValueError(
            f"{str(path)!r}: stable-baselines3 cannot load it as a PPO model "
            f"({type(err).__name__}{': ' + cause if cause else ''})"
        ) from err


def _recurrent_policy(data: bytes) -> bool:
    """Whether a saved model's ``data`` names a recurrent policy class (sb3-contrib's)."""
    import json

    try:
        policy_class = json.loads(data).get("policy_class", {})
    except (ValueError, AttributeError):  # not JSON: PPO.load says what is wrong
        return False
    module = policy_class.get("__module__", "") if isinstance(policy_class, dict) else ""
    return isinstance(module, str) and module.startswith("sb3_contrib.common.recurrent")


#: PPO models loaded in this process, by resolved path and file version (:func:`_load_ppo`), at
#: most 8.
_MODELS: dict[Any, Any] = {}


def _load_ppo(path: Path) -> Any:
    """A PPO model (:func:`load_ppo`, its errors naming ``path`` as given), loaded once per
    process and file version (the policy is stateless; a file saved again is loaded again)."""
    try:
        stat = path.stat()
        key: Any = (str(path.resolve()), stat.st_mtime_ns, stat.st_size)
    except OSError:
        key = str(path)  # load_ppo names what is wrong with it
    if key not in _MODELS:
        model = load_ppo(path)
        if len(_MODELS) >= 8:
            _MODELS.pop(next(iter(_MODELS)))
        _MODELS[key] = model
    return _MODELS[key]


def adaptation(spec: str) -> tuple[int, int]:
    """The budget and seed of a ``ppo@STEPS[:SEED]`` spec ((0, 0) for ``ppo``), or a
    ValueError."""
    base, _ = _split(spec)
    if base == SHIPPED:
        return 0, 0
    steps, sep, seed = base[len(SHIPPED) + 1 :].partition(":")
    if not base.startswith(SHIPPED + "@") or not steps.isdigit() or (sep and not seed.isdigit()):
        raise ValueError(
            f"policy={spec!r}: write ppo@STEPS or ppo@STEPS:SEED, STEPS and SEED integers >= 0"
        )
    return int(steps), int(seed) if sep else 0


def adapt_steps(spec: str) -> int:
    """The adaptation budget of a ``ppo@STEPS[:SEED]`` spec (0 for ``ppo``), or a ValueError."""
    return adaptation(spec)[0]


def adapt_seed(spec: str) -> int:
    """The adaptation's seed of a ``ppo@STEPS:SEED`` spec (0 without ``:SEED``), or a
    ValueError."""
    return adaptation(spec)[1]


def adapted_path(env: Any, steps: int, population: str | None = None, seed: int = 0) -> Path:
    """The shipped user of ``env``'s task adapted to ``env``'s cell by ``steps`` steps with
    random seed ``seed``, with the human variability of ``population`` (the spec's
    ``+<population>``) around it where that population has one
    (:func:`agents.learned.adapt.adapted_user`)."""
    from agents.learned.adapt import adapted_user
    from agents.learned.models import cell_of

    u = env.unwrapped
    settings = {"task": u.task_name, "config": u.config, "sensors": u.sensors}
    settings["estimators"] = u.estimators
    cell = cell_of(settings, getattr(u, "technique", None))
    condition = None if cell["condition"] == "custom" else cell["condition"]
    varies = population is not None and POPULATIONS[population].variability
    return adapted_user(
        cell["task"],
        u.technique,
        cell["population"],
        condition,
        steps,
        seed=seed,
        variability=population if varies else None,
    )


def build_policy(spec: str, env: Any) -> Any:
    """The policy ``spec`` names, built for ``env`` (see the module docstring)."""
    check_policy(spec)
    base, population = _split(spec)
    policy: Any
    if base in POLICIES:
        policy = _scripted(base, env)
    elif base.endswith(".zip"):
        policy = LearnedPolicy(base, env)
    elif base == SHIPPED:
        from agents.learned.users import shipped_user

        user = shipped_user(env.unwrapped.task_name)
        policy = LearnedPolicy(user.path, env)
        policy.name = SHIPPED
    elif base.startswith(SHIPPED + "@"):
        steps, seed = adaptation(spec)
        policy = LearnedPolicy(adapted_path(env, steps, population, seed), env)
        policy.name = base
    else:
        from estimators.registry import load_attr

        policy = load_attr(base, "policy")(env)
        for method in ("reset", "act"):
            if not callable(getattr(policy, method, None)):
                raise ValueError(
                    f"policy={spec!r} built a {type(policy).__name__} without a {method}() "
                    "method (a policy has reset(rng=None, rows=None) and act(obs))"
                )
    if population is None or not POPULATIONS[population].variability:
        return policy
    params = VariabilityParams.from_population(population)
    return HumanVariability(policy, params, population=population)
