"""Scripted simulated users: policies that act on what the user sees in VR, and nothing else.

A policy is a small class with ``reset(rng=None, rows=None)`` and ``act(obs) -> action``
(:class:`Policy`); ``obs`` is one observation ``(n,)`` or a batch ``(B, n)`` from the vector env.
Policies read the observation only (decoded with the env's
:class:`~vrloco_env.observation.ObservationSpec`): the virtual heading, the goal bearing and
distance and the ray ranges seen from the *virtual* pose (what the headset shows), the detected
steps, and for Interact the hand error — never the ground truth in ``info``. What a user knows
about their own body (how far one detected step carries them in VR, their width) is in
:class:`PolicyParams`.

Modules:

* :mod:`agents.scripted.observation` — :class:`ObservationLayout`, :class:`ObsView` and the ray
  geometry (:func:`ray_points`, :func:`free_lengths`).
* :mod:`agents.scripted.base` — :class:`Policy`, :func:`is_batched`, :class:`PolicyParams`,
  :func:`params_from_env` and :class:`ScriptedPolicy` (decoding, per-row state, the walk gate,
  the hand).
* :mod:`agents.scripted.planner` — the goal seeker's compiled route planner.
* One module per user:

  * :mod:`agents.scripted.goal_seeker` — :class:`GoalSeeker`: turn toward the goal, step when
    aligned, re-align when the bearing error grows, along the shortest way around what it has
    seen (a map of the ray hits).
  * :mod:`agents.scripted.avoid_manoeuvre` — :class:`AvoidManoeuvre`: Zhang 2021's Fig. 5
    manoeuvre: turn away from an obstacle ahead, step, turn back to the original heading.
  * :mod:`agents.scripted.reactive_avoider` — :class:`ReactiveAvoider`: a potential field on the
    current rays (Khatib 1986), no memory.

This module holds the registry :data:`POLICIES` and :func:`make_policy`. A new scripted user is a
new module with a :class:`ScriptedPolicy` subclass (its ``name`` and ``_steer``) and one line in
:data:`POLICIES`.
"""

from __future__ import annotations

from typing import Any

from agents.scripted.avoid_manoeuvre import AvoidManoeuvre
from agents.scripted.base import Policy, PolicyParams, ScriptedPolicy, is_batched, params_from_env
from agents.scripted.goal_seeker import GoalSeeker
from agents.scripted.observation import ObservationLayout, ObsView, free_lengths, ray_points
from agents.scripted.reactive_avoider import ReactiveAvoider
from estimators.registry import Registry

__all__ = [
    "POLICIES",
    "AvoidManoeuvre",
    "GoalSeeker",
    "ObsView",
    "ObservationLayout",
    "Policy",
    "PolicyParams",
    "ReactiveAvoider",
    "ScriptedPolicy",
    "free_lengths",
    "is_batched",
    "make_policy",
    "params_from_env",
    "ray_points",
]


#: The scripted users, by name (each class's ``name``).
POLICIES: Registry[type[ScriptedPolicy]] = Registry("policy")
POLICIES.register(
    GoalSeeker.name,
    GoalSeeker,
    "turn toward the goal, step when aligned, along the shortest way around what it has seen",
)
POLICIES.register(
    AvoidManoeuvre.name,
    AvoidManoeuvre,
    "Zhang 2021's Fig. 5 manoeuvre: turn away from an obstacle ahead, step, turn back",
)
POLICIES.register(
    ReactiveAvoider.name, ReactiveAvoider, "a potential field on the current rays, no memory"
)


def make_policy(
    name: str,
    layout: ObservationLayout | None = None,
    params: PolicyParams | None = None,
    **kwargs: Any,
) -> ScriptedPolicy:
    """A scripted user by name: ``goal_seeker``, ``avoid_manoeuvre`` or ``reactive_avoider``.

    Raises:
        ValueError: an unknown name (the valid ones are listed).
    """
    return POLICIES.get(name)(layout, params, **kwargs)
