"""User populations: seeded distributions of how simulated humans move their head and body.

A :class:`Population` is one dataclass of distributions. Each ``(lo, hi)`` field is a uniform
range a user's value is drawn from at every episode start (from that user's own stream, see
:class:`vrloco_env.user.behaviour.GazeBehaviour`); a plain number is the same for everyone.
Two halves:

* the **simulated human's head and body** (env side,
  :attr:`vrloco_env.config.EnvConfig.population`): gaze behaviour (looking at the goal, glancing at
  what is near, looking down at the hand while interacting, idle scans), nods and the step impact
  (head bob) — run by :class:`~vrloco_env.user.behaviour.GazeBehaviour` on top of what the action
  asks for;
* the **agent-side variability** of :class:`agents.variability.HumanVariability` (reaction delay,
  turn overshoot, cadence bias and jitter), taken by ``"<policy>+<population>"`` policy specs
  (:mod:`agents.policies`).

Registered (:data:`POPULATIONS`; :func:`get_population` raises naming them):

* ``idealised`` — no behaviour, no variability: today's scripted user, bit for bit.
* ``human`` — the agent-side variability that ``+human`` has always meant, with an idealised
  head (its env side does nothing).
* ``typical`` — ``human``'s variability plus a head that looks where it goes: at the goal, at
  what comes near, down at the hand, with occasional idle scans and nods.
* ``gaze_scanners`` — ``typical`` with frequent, wide head scans and head-movers' small eye-only
  range: the users on whom walking where the head looks goes wrong.
* ``nodders`` — ``typical``'s gaze with frequent nod bouts: the users on whom a head-IMU step
  detector sees phantom steps.

Where the numbers come from (each field's doc says which): head-movement kinematics are the
motion model's (:attr:`vrloco_env.user.motion.MotionParams.head_turn_lag_s`); the eye-only range
before the head joins a gaze shift from Stahl (Exp. Brain Res. 126, 1999) and the VR studies of
Sidenmark & Gellersen (ACM TOCHI 27(1), 2019) and Hu, Sidenmark, Lee & Gellersen (the eye-head
mover spectrum, arXiv:2602.06164, 2026: a hinge model of head contribution against target
eccentricity, varying widely between people); nods from Hadar, Steiner, Grant & Rose (Hum. Mov.
Sci. 2, 1983: nods of a few to ~15 deg), Hale, Ward, Buccheri, Oliver & Hamilton (J. Nonverbal
Behav. 44, 2020: listener nodding at 2.6-6.5 Hz, slower nods below ~1.1 Hz) and Mori, Den &
Jokinen (PLoS ONE 20(5), 2025: a nod is one to a few up-down cycles); glances at obstacles
one to two steps ahead from Patla & Vickers (NeuroReport 8, 1997). How *often* people scan,
glance and nod while walking in place in VR is not measured in those studies: those rates are
engineering choices, stated as such, spanning "rarely" to "often" across the populations — not
set to make any technique win or lose.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

from estimators.validation import check_bool, check_in_range, check_numbers, value_repr

__all__ = ["POPULATIONS", "RANGE_FIELDS", "Population", "get_population", "population_names"]


@dataclass(frozen=True)
class Population:
    """Distributions of one user population (see the module docstring). ``(lo, hi)`` fields are
    uniform ranges drawn per user and episode.

    Attributes:
        name: the registry name.
        description: one line.
        gaze: the head turns on the torso at all (goal, glances, scans). False: the head stays
            straight on the torso (nods and bob still apply).
        eye_range_deg: gaze offsets up to this (deg) are taken by the eyes alone; the head turns
            by the rest (the hinge of the eye-head mover spectrum; Stahl 1999 reports eye-only
            ranges of roughly 10-25 deg varying between subjects, Sidenmark & Gellersen 2019
            find most VR gaze shifts beyond ~25 deg carried mainly by the head).
        max_head_yaw_deg: the head-on-torso yaw target is clipped to +- this (deg); adults'
            active axial neck rotation is ~70-80 deg each way (Ferrario et al. 2002).
        gaze_onset_s: the head stays straight this long (s) after an episode starts, the time
            to see the scene and start a gaze shift: saccade latencies are ~0.2 s (Carpenter,
            Movements of the Eyes, 1988) and simple visual reaction times 0.2-0.25 s
            (Woods et al., Front. Hum. Neurosci. 9:131, 2015).
        glance_rate_hz: onsets per second of a glance at the nearest thing the rays see within
            ``glance_range_m`` (an engineering choice).
        glance_range_m: what is nearer than this (m) draws glances: about two steps ahead
            (Patla & Vickers 1997 find obstacles fixated one to two steps before crossing).
        glance_cone_deg: only what lies within +- this (deg) of the torso's direction, the
            travel path, draws glances. Walkers fixate obstacles in their travel path one to
            two steps ahead (Patla & Vickers 1997) and avoid what is beside the path with
            peripheral vision, without fixating it (Marigold, Weerdesteyn, Patla & Duysens,
            Exp. Brain Res. 176, 2007); 30 deg is about half a body width (0.3 m) beside the
            path one step (0.6 m) ahead, atan(0.3 / 0.6) = 27 deg (an engineering choice from
            that geometry). Walls beside a corridor do not draw glances.
        glance_s: duration of a glance (s).
        scan_rate_hz: onsets per second of an idle look around (an engineering choice).
        scan_amplitude_deg: a scan looks at a direction drawn uniformly within +- this gaze
            angle of the torso (deg), per scan.
        scan_s: duration of a scan (s).
        look_down_deg: head pitch (deg, down) while interacting with the hand in the goal region
            (looking at a hand held at chest height in front of the body).
        nod_rate_hz: onsets per second of a nod bout (an engineering choice).
        nod_amplitude_deg: peak pitch of a nod (deg); Hadar et al. 1983: a few to ~15 deg.
        nod_frequency_hz: a user's nodding frequency (Hz); Hale et al. 2020 find slow nods below
            ~1.1 Hz and fast listener nods at 2.6-6.5 Hz.
        nod_cycles: cycles per nod bout (Mori et al. 2025: one to a few).
        bob_scale: factor on the user's step impact (vertical head acceleration per step)
            drawn by the motion model (heavier or lighter steppers). An engineering choice: the
            seed papers give no spread between users; ``typical``'s 0.8-1.25 keeps the
            specific-force peaks within roughly 1.1-1.6 g, about seed 000 Fig. 2's range.
        reaction_delay_s, reaction_delay_sd_s, overshoot, overshoot_sd, cadence_bias_sd,
            cadence_jitter_sd: the agent-side variability
            (:class:`agents.variability.VariabilityParams`, whose docs give the evidence);
            ``variability`` False leaves the policy unwrapped.
        variability: the population carries agent-side variability.
        wip_drift_mps: forward drift speed (m/s) of the user's standing spot while stepping in
            place (:mod:`vrloco_env.user.play_area`; Nilsson, Serafin & Nordahl, IEEE 3DUI
            2014, measure such unintended drift; the few-cm/s ranges here are engineering
            choices). The last ``(lo, hi)`` field, so it is drawn last.
    """

    name: str
    description: str
    gaze: bool = False
    eye_range_deg: tuple[float, float] = (15.0, 25.0)
    max_head_yaw_deg: float = 70.0
    gaze_onset_s: tuple[float, float] = (0.2, 0.3)
    glance_rate_hz: tuple[float, float] = (0.0, 0.0)
    glance_range_m: float = 1.5
    glance_cone_deg: float = 30.0
    glance_s: tuple[float, float] = (0.4, 0.8)
    scan_rate_hz: tuple[float, float] = (0.0, 0.0)
    scan_amplitude_deg: tuple[float, float] = (40.0, 70.0)
    scan_s: tuple[float, float] = (0.6, 1.5)
    look_down_deg: tuple[float, float] = (0.0, 0.0)
    nod_rate_hz: tuple[float, float] = (0.0, 0.0)
    nod_amplitude_deg: tuple[float, float] = (5.0, 15.0)
    nod_frequency_hz: tuple[float, float] = (1.5, 2.5)
    nod_cycles: tuple[float, float] = (2.0, 4.0)
    bob_scale: tuple[float, float] = (1.0, 1.0)
    variability: bool = False
    reaction_delay_s: float = 0.25
    reaction_delay_sd_s: float = 0.05
    overshoot: float = 0.1
    overshoot_sd: float = 0.05
    cadence_bias_sd: float = 0.1
    cadence_jitter_sd: float = 0.05
    wip_drift_mps: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"Population.name={self.name!r}: must be a non-empty string")
        check_bool(self, "gaze")
        check_bool(self, "variability")
        limits = {
            "eye_range_deg": (0.0, 45.0, "deg"), "gaze_onset_s": (0.0, 2.0, "s"),
            "glance_rate_hz": (0.0, 2.0, "Hz"),
            "glance_s": (0.1, 5.0, "s"), "scan_rate_hz": (0.0, 2.0, "Hz"),
            "scan_amplitude_deg": (0.0, 120.0, "deg"), "scan_s": (0.1, 10.0, "s"),
            "look_down_deg": (0.0, 45.0, "deg"), "nod_rate_hz": (0.0, 2.0, "Hz"),
            "nod_amplitude_deg": (0.0, 30.0, "deg"), "nod_frequency_hz": (0.2, 3.0, "Hz"),
            "nod_cycles": (0.5, 10.0, "cycles"), "bob_scale": (0.2, 3.0, ""),
            "wip_drift_mps": (0.0, 0.5, "m/s"),
        }  # fmt: skip
        for name, (lo, hi, unit) in limits.items():
            check_numbers(self, name, lo, hi, unit, length=2, ordered=True)
        check_in_range(self, "max_head_yaw_deg", 0.0, 80.0, "deg")
        check_in_range(self, "glance_range_m", 0.0, 10.0, "m")
        check_in_range(self, "glance_cone_deg", 0.0, 180.0, "deg")
        check_in_range(self, "reaction_delay_s", 0.0, 1.0, "s")
        for name in ("reaction_delay_sd_s", "overshoot", "overshoot_sd"):
            check_in_range(self, name, 0.0, 2.0)
        for name in ("cadence_bias_sd", "cadence_jitter_sd"):
            check_in_range(self, name, 0.0, 1.0)

    @property
    def moves_head(self) -> bool:
        """The env side does something: the head turns, nods, looks down or the bob differs."""
        return (
            self.gaze
            or self.nod_rate_hz[1] > 0.0
            or self.look_down_deg[1] > 0.0
            or self.bob_scale != (1.0, 1.0)
        )


#: The ``(lo, hi)`` fields of :class:`Population`, in the order a user's values are drawn.
RANGE_FIELDS = tuple(
    f.name for f in fields(Population) if f.type in ("tuple[float, float]", tuple[float, float])
)

_TYPICAL_HEAD = dict(
    gaze=True,
    eye_range_deg=(15.0, 25.0),
    glance_rate_hz=(0.1, 0.3),
    scan_rate_hz=(0.02, 0.08),
    scan_amplitude_deg=(30.0, 60.0),
    look_down_deg=(20.0, 35.0),
    nod_rate_hz=(0.0, 0.03),
    bob_scale=(0.8, 1.25),
    variability=True,
    wip_drift_mps=(0.01, 0.05),
)

POPULATIONS: dict[str, Population] = {
    p.name: p
    for p in (
        Population("idealised", "no head behaviour, no variability: the idealised scripted user"),
        Population("human", "reaction delay, turn overshoot and cadence variation; head straight",
                   variability=True),
        Population("typical", "looks at the goal and at what is near, down at the hand; "
                   "occasional scans and nods", **_TYPICAL_HEAD),
        Population("gaze_scanners", "head-movers who look around often and widely while walking",
                   **{**_TYPICAL_HEAD, "eye_range_deg": (5.0, 12.0), "scan_rate_hz": (0.2, 0.4),
                      "scan_amplitude_deg": (45.0, 80.0)}),
        Population("nodders", "typical gaze with frequent nod bouts",
                   **{**_TYPICAL_HEAD, "nod_rate_hz": (0.1, 0.25)}),
    )
}  # fmt: skip


def population_names() -> tuple[str, ...]:
    """The registered population names."""
    return tuple(POPULATIONS)


def get_population(name: str | Population, field: str = "population") -> Population:
    """The population ``name`` (a registered name or a :class:`Population`).

    Raises:
        ValueError: an unknown name, naming ``field`` and the registered names.
    """
    if isinstance(name, Population):
        return name
    if isinstance(name, str) and name in POPULATIONS:
        return POPULATIONS[name]
    raise ValueError(
        f"{field}={value_repr(name)}: must be one of {', '.join(POPULATIONS)} (or a Population)"
    )
