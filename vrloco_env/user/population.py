"""User populations: seeded distributions of how simulated humans move their head and body.

A :class:`Population` is one dataclass of distributions. Each ``(lo, hi)`` field is a uniform
range a user's value is drawn from at every episode start (from that user's own stream, see
:class:`vrloco_env.user.behaviour.GazeBehaviour`); a plain number is the same for everyone.
Two halves:

* the **simulated human's head and body** (env side,
  :attr:`vrloco_env.config.EnvConfig.population`): gaze behaviour (looking at the goal, glancing at
  what is near while walking, looking down at the hand while interacting, looking around), the
  head's turning speed, nods, the head's yaw oscillation per stride, the step impact (head bob)
  and the drift of stepping in place — run by :class:`~vrloco_env.user.behaviour.GazeBehaviour`
  on top of what the action asks for;
* the **agent-side variability** of :class:`agents.benchmark.variability.HumanVariability`
  (reaction delay, turn overshoot, cadence bias and jitter), taken by
  ``"<policy>+<population>"`` policy specs (:mod:`agents.benchmark.policies`).

Registered (:data:`POPULATIONS`; :func:`get_population` raises naming them):

* ``idealised`` — no behaviour, no variability: today's scripted user, bit for bit.
* ``human`` — the agent-side variability that ``+human`` has always meant, with an idealised
  head (its env side does nothing).
* ``typical`` — ``human``'s variability plus a head that looks where it goes: at the goal, at
  what comes near, down at the hand, with occasional looks around and nods.
* ``gaze_scanners`` — ``typical`` with frequent, wide looks around and head-movers' small
  eye-only range: the users on whom walking where the head looks goes wrong.
* ``nodders`` — ``typical``'s gaze with frequent nod bouts: the users on whom a head-IMU step
  detector sees phantom steps.

Where the numbers come from (each field's doc says which: a source, a fit, a bound or a choice):

* **Real head traces** (:mod:`agents.recordings.head_traces`, ``$VRLOCO_DATA/head_traces``):
  people seated or standing, freely viewing 360-degree videos (Corbillon et al., Lo et al., Wu et
  al., ACM MMSys 2017) — **nobody walked**. Free viewing of a 360-degree video invites more looking
  around than waiting in a VR room, so these traces are an upper bound for the *rate* of idle
  looking and a model for the *shape* of a gaze shift: the sizes, speeds and intervals of the
  head's turns. Only the tuning files (even video numbers, :func:`agents.experiments.
  head_behaviour.is_held_out`) were used; the odd ones are held out for the report (``vrloco
  experiment head-behaviour``). The fits match :mod:`agents.recordings.head_motion_stats`'s
  statistics at 10 Hz of simulated users standing with the goal straight ahead and nothing near, 300
  users of 60 s (seeds 1000-1299), against those of each tuning dataset (corbillon2017 / lo2017 /
  wu2017): turn amplitude quartiles 15.5/25.2/46.4, 17.7/30.0/59.0 and 17.3/30.0/64.4 deg;
  inter-turn intervals p10/p25/p50 0.5/0.9/1.6, 0.6/1.0/1.8 and 0.7/1.1/1.9 s; the main
  sequence (a turn's peak 10-Hz speed by amplitude, 10-20/20-30/30-45/45-60/60-90 deg) 52/70/
  87/102/117, 55/78/98/111/138 and 44/61/75/88/107 deg/s; turns of at least 10 deg 19.7, 19.5
  and 15.6 per minute; nod-like events 4.3, 4.0 and 3.7 per minute.
* **Walking studies** bound the head while stepping: head rotations during locomotor tasks do
  not exceed 38 deg and 185 deg/s (Pozzo, Berthoz & Lefort, Exp. Brain Res. 82, 1990, abstract);
  the head yaws once per stride, at half the stepping rate (Grasso, Glasauer, Takei & Berthoz,
  "Gaze anticipation contributes to steering in locomotion", chapter abstract); head-in-space
  motion while walking lies below 4 Hz (Cromwell et al., J. Motor Behav. 33(1), 2001); group
  median maximal head velocity walking in place below 90 deg/s (Grossman et al., Exp. Brain
  Res. 70, 1988, abstract); 40-deg gaze shifts while walking start the head 262 ms after the
  target moves (Peters, van Emmerik & Bloomberg, Gait & Posture 2006, NASA JSC report).
* **Stepping in place**: the Fukuda stepping test (:mod:`vrloco_env.user.play_area`).
* The eye-only range before the head joins a gaze shift from Stahl (Exp. Brain Res. 126, 1999)
  and the VR studies of Sidenmark & Gellersen (ACM TOCHI 27(1), 2019) and Hu, Sidenmark, Lee &
  Gellersen (the eye-head mover spectrum, arXiv:2602.06164, 2026: a hinge model of head
  contribution against target eccentricity, varying widely between people); nods from Hadar,
  Steiner, Grant & Rose (Hum. Mov. Sci. 2, 1983: nods of a few to ~15 deg), Hale, Ward,
  Buccheri, Oliver & Hamilton (J. Nonverbal Behav. 44, 2020: listener nodding at 2.6-6.5 Hz,
  slower nods below ~1.1 Hz) and Mori, Den & Jokinen (PLoS ONE 20(5), 2025: a nod is one to a
  few up-down cycles); glances at obstacles one to two steps ahead from Patla & Vickers
  (NeuroReport 8, 1997).
* **Choices.** How *often* people look around, glance and nod while walking in place in VR is
  not measured in those studies: those rates are engineering choices, stated as such with their
  low/high range, spanning "rarely" to "often" across the populations (within the 360-video
  bound where it applies) — not set to make any technique win or lose.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

from estimators.registry import Registry
from estimators.validation import check_bool, check_in_range, check_numbers

__all__ = ["POPULATIONS", "RANGE_FIELDS", "Population", "get_population", "population_names"]


@dataclass(frozen=True)
class Population:
    """Distributions of one user population (see the module docstring). ``(lo, hi)`` fields are
    uniform ranges drawn per user and episode.

    Attributes:
        name: the registry name.
        description: one line.
        gaze: the head turns on the torso at all (goal, glances, looks around). False: the head
            stays straight on the torso (nods, the stride oscillation and bob still apply).
        eye_range_deg: gaze offsets up to this (deg) are taken by the eyes alone; the head turns
            by the rest (the hinge of the eye-head mover spectrum; Stahl 1999 reports eye-only
            ranges of roughly 10-25 deg varying between subjects, Sidenmark & Gellersen 2019
            find most VR gaze shifts beyond ~25 deg carried mainly by the head). A source.
        max_head_yaw_deg: the head-on-torso yaw target is clipped to +- this (deg); adults'
            active axial neck rotation is ~70-80 deg each way (Ferrario et al. 2002). A source.
        gaze_onset_s: the head stays straight this long (s) after an episode starts, the time
            to see the scene and start a gaze shift: saccade latencies are ~0.2 s (Carpenter,
            Movements of the Eyes, 1988), simple visual reaction times 0.2-0.25 s (Woods et al.,
            Front. Hum. Neurosci. 9:131, 2015), and the head starts a 40-deg gaze shift made
            while walking 262 ms after the target moves (Peters et al. 2006). A source.
        head_accel_deg_s2: peak angular acceleration (deg/s^2) of the head's turns on the torso
            (:meth:`vrloco_env.user.behaviour.GazeBehaviour.intent`): a turn of amplitude A
            peaks at about sqrt(accel * A), a main sequence that saturates as the tuning
            traces' does (their turns' peak 10-Hz speed grows as about 13-15 sqrt(A) deg/s).
            A fit: the range (300, 500) gives the simulated main sequence 48/66/85/104/121
            deg/s (10-20 ... 60-90 deg), against the tuning datasets' 44-55/61-78/75-98/
            88-111/107-138 (the module docstring); a narrower or faster range matched worse.
        glance_rate_hz: onsets per second of a glance at the nearest thing the rays see within
            ``glance_range_m`` while stepping. A choice: ``typical`` (0.1, 0.3), "now and then"
            to "every few seconds" while something is near.
        glance_range_m: what is nearer than this (m) draws glances: about two steps ahead
            (Patla & Vickers 1997 find obstacles fixated one to two steps before crossing).
        glance_cone_deg: only what lies within +- this (deg) of the torso's direction, the
            travel path, draws glances, and only while the user steps (a standing user has no
            travel path). Walkers fixate obstacles in their travel path one to two steps ahead
            (Patla & Vickers 1997) and avoid what is beside the path with peripheral vision,
            without fixating it (Marigold, Weerdesteyn, Patla & Duysens, Exp. Brain Res. 176,
            2007); 30 deg is about half a body width (0.3 m) beside the path one step (0.6 m)
            ahead, atan(0.3 / 0.6) = 27 deg (an engineering choice from that geometry). Walls
            beside a corridor do not draw glances.
        glance_s: duration of a glance (s). A choice, (0.4, 0.8) for every population: a look
            at an obstacle one to two steps ahead lasts under a step or two.
        scan_rate_hz: onsets per second of a bout of looking around (standing or walking). A
            choice bounded by the 360-video traces: standing with the goal ahead, ``typical``'s
            (0.02, 0.08) makes 5.4 head turns of at least 10 deg per minute and
            ``gaze_scanners``' (0.06, 0.12) 11.5, below the 15.6-19.7 of free 360-degree
            viewing (the upper bound).
        scan_amplitude_deg: a look shifts the gaze from where it is (the goal, or the bout's
            last look) by an exponential size of this mean (deg), left or right alike; the head
            takes what the eyes do not. A fit: ``typical``'s (10, 40) gives turn amplitude
            quartiles 18.7/31.1/52.8 deg against the tuning datasets' 15.5-17.7/25.2-30.0/
            46.4-64.4 (the module docstring). ``gaze_scanners``' (20, 50) is a choice at the
            wide end (21.3/36.9/62.2).
        scan_s: mean time a look is held (s; exponential holds). A fit, with ``scan_looks``:
            ``typical``'s (0.4, 1.0) gives inter-turn intervals p10/p25/p50 0.7/1.0/1.7 s against
            the tuning datasets' 0.5-0.7/0.9-1.1/1.6-1.9 (their longer intervals, p75 and above,
            are set by the bounded bout rate).
        scan_looks: mean looks per bout while standing (geometric: each look is followed by
            another with chance 1 - 1 / this); walking, a bout is one look. A choice (4, 10)
            constrained by the intervals: with fewer looks per bout most intervals fall between
            bouts and the median interval exceeds the tuning files'.
        walking_head_deg: while the user steps, a glance or look turns the head at most this far
            (deg) from where looking at the goal holds it: head rotations during locomotion stay
            within 38 deg (Pozzo et al. 1990). A bound; walking straight, turns larger than
            38 deg come only from a glance meeting a look (``typical`` 0.02 per minute, 2 % of
            its turns of at least 10 deg; ``gaze_scanners`` 0.18, 3 %) and none is faster than
            185 deg/s (peaks below 120 deg/s; 100 users stepping 60 s at 117 steps/min,
            ``tests/test_vrloco_env/user/test_calibration.py``).
        look_down_deg: head pitch (deg, down) while interacting with the hand in the goal region
            (looking at a hand held at chest height in front of the body). A choice, (20, 35)
            for ``typical``.
        nod_rate_hz: onsets per second of a nod bout. A choice: ``typical``'s (0, 0.015) gives
            3.5 nod-like events per minute standing, below the 3.7-4.3 of the tuning traces;
            ``nodders``' (0.1, 0.25) is far above them on purpose (the stress population).
        nod_amplitude_deg: peak pitch of a nod (deg); Hadar et al. 1983: a few to ~15 deg.
        nod_frequency_hz: a user's nodding frequency (Hz); Hale et al. 2020 find slow nods below
            ~1.1 Hz and fast listener nods at 2.6-6.5 Hz; below the 4 Hz of head-in-space
            motion while walking (Cromwell et al. 2001).
        nod_cycles: cycles per nod bout (Mori et al. 2025: one to a few).
        stride_yaw_deg: amplitude (deg) of the head's yaw oscillation while stepping, at half
            the stepping rate (once per stride: Grasso et al.). The frequency is a source; the
            amplitude a choice, (1, 3) for ``typical``: its peak speed, 2 pi (c / 2) A, stays
            below 21 deg/s at 2.2 steps/s, well inside the 90 deg/s of Grossman et al. 1988.
        bob_scale: factor on the user's step impact (vertical head acceleration per step)
            drawn by the motion model (heavier or lighter steppers). An engineering choice: the
            seed papers give no spread between users; ``typical``'s 0.8-1.25 keeps the
            specific-force peaks within roughly 1.1-1.6 g, about Zhang 2021 Fig. 2's range.
        reaction_delay_s, reaction_delay_sd_s, overshoot, overshoot_sd, cadence_bias_sd,
            cadence_jitter_sd: the agent-side variability
            (:class:`agents.benchmark.variability.VariabilityParams`, whose docs give the evidence);
            ``variability`` False leaves the policy unwrapped.
        variability: the population carries agent-side variability.
        wip_drift_mps: forward drift speed (m/s) of the user's standing spot while stepping in
            place (:mod:`vrloco_env.user.play_area`; every healthy subject of Grostern et al.
            2021 drifted forward; the magnitudes are engineering choices, 1-5 cm/s for
            ``typical``).
        wip_turn_deg_per_step: the body's turning drift while stepping in place (deg per step,
            counter-clockwise positive, :mod:`vrloco_env.user.play_area`). A bound: ``typical``'s
            +-0.45 deg/step turns at most 45 deg in 100 steps and 22.5 deg in 50, inside the
            Fukuda cut-offs (30 deg in 50 steps, 45 deg in 100) for healthy adults, left or
            right. The last ``(lo, hi)`` field, so it is drawn last.
    """

    name: str
    description: str
    gaze: bool = False
    eye_range_deg: tuple[float, float] = (15.0, 25.0)
    max_head_yaw_deg: float = 70.0
    gaze_onset_s: tuple[float, float] = (0.2, 0.3)
    head_accel_deg_s2: tuple[float, float] = (300.0, 500.0)
    glance_rate_hz: tuple[float, float] = (0.0, 0.0)
    glance_range_m: float = 1.5
    glance_cone_deg: float = 30.0
    glance_s: tuple[float, float] = (0.4, 0.8)
    scan_rate_hz: tuple[float, float] = (0.0, 0.0)
    scan_amplitude_deg: tuple[float, float] = (10.0, 40.0)
    scan_s: tuple[float, float] = (0.4, 1.0)
    scan_looks: tuple[float, float] = (4.0, 10.0)
    walking_head_deg: float = 38.0
    look_down_deg: tuple[float, float] = (0.0, 0.0)
    nod_rate_hz: tuple[float, float] = (0.0, 0.0)
    nod_amplitude_deg: tuple[float, float] = (5.0, 15.0)
    nod_frequency_hz: tuple[float, float] = (1.5, 2.5)
    nod_cycles: tuple[float, float] = (2.0, 4.0)
    stride_yaw_deg: tuple[float, float] = (0.0, 0.0)
    bob_scale: tuple[float, float] = (1.0, 1.0)
    variability: bool = False
    reaction_delay_s: float = 0.25
    reaction_delay_sd_s: float = 0.05
    overshoot: float = 0.1
    overshoot_sd: float = 0.05
    cadence_bias_sd: float = 0.1
    cadence_jitter_sd: float = 0.05
    wip_drift_mps: tuple[float, float] = (0.0, 0.0)
    wip_turn_deg_per_step: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"Population.name={self.name!r}: must be a non-empty string")
        check_bool(self, "gaze")
        check_bool(self, "variability")
        limits = {
            "eye_range_deg": (0.0, 45.0, "deg"),
            "gaze_onset_s": (0.0, 2.0, "s"),
            "head_accel_deg_s2": (10.0, 10000.0, "deg/s^2"),
            "glance_rate_hz": (0.0, 2.0, "Hz"),
            "glance_s": (0.1, 5.0, "s"),
            "scan_rate_hz": (0.0, 2.0, "Hz"),
            "scan_amplitude_deg": (0.0, 120.0, "deg"),
            "scan_s": (0.1, 10.0, "s"),
            "scan_looks": (1.0, 20.0, "looks"),
            "stride_yaw_deg": (0.0, 10.0, "deg"),
            "look_down_deg": (0.0, 45.0, "deg"),
            "nod_rate_hz": (0.0, 2.0, "Hz"),
            "nod_amplitude_deg": (0.0, 30.0, "deg"),
            "nod_frequency_hz": (0.2, 3.0, "Hz"),
            "nod_cycles": (0.5, 10.0, "cycles"),
            "bob_scale": (0.2, 3.0, ""),
            "wip_drift_mps": (0.0, 0.5, "m/s"),
            "wip_turn_deg_per_step": (-1.0, 1.0, "deg/step"),
        }
        for name, (lo, hi, unit) in limits.items():
            check_numbers(self, name, lo, hi, unit, length=2, ordered=True)
        check_in_range(self, "max_head_yaw_deg", 0.0, 80.0, "deg")
        check_in_range(self, "glance_range_m", 0.0, 10.0, "m")
        check_in_range(self, "glance_cone_deg", 0.0, 180.0, "deg")
        check_in_range(self, "walking_head_deg", 0.0, 80.0, "deg")
        check_in_range(self, "reaction_delay_s", 0.0, 1.0, "s")
        for name in ("reaction_delay_sd_s", "overshoot", "overshoot_sd"):
            check_in_range(self, name, 0.0, 2.0)
        for name in ("cadence_bias_sd", "cadence_jitter_sd"):
            check_in_range(self, name, 0.0, 1.0)

    @property
    def moves_head(self) -> bool:
        """The env side does something: the head turns, nods, sways per stride or looks down,
        the bob differs, or the body drifts in turning while stepping in place."""
        return (
            self.gaze
            or self.nod_rate_hz[1] > 0.0
            or self.look_down_deg[1] > 0.0
            or self.stride_yaw_deg[1] > 0.0
            or self.bob_scale != (1.0, 1.0)
            or self.wip_turn_deg_per_step != (0.0, 0.0)
        )


#: The ``(lo, hi)`` fields of :class:`Population`, in the order a user's values are drawn.
RANGE_FIELDS = tuple(
    f.name for f in fields(Population) if f.type in ("tuple[float, float]", tuple[float, float])
)

#: The ``(lo, hi)`` fields whose doc calls them a choice (no evidence sets them), in
#: :data:`RANGE_FIELDS` order: the ranges ``vrloco experiment population-sensitivity``
#: collapses to each end (:mod:`agents.experiments.population_sensitivity`).
CHOICE_FIELDS: tuple[str, ...] = (
    "glance_rate_hz",
    "glance_s",
    "scan_rate_hz",
    "scan_looks",
    "look_down_deg",
    "nod_rate_hz",
    "stride_yaw_deg",
    "bob_scale",
    "wip_drift_mps",
)

_TYPICAL_HEAD = dict(
    gaze=True,
    eye_range_deg=(15.0, 25.0),
    glance_rate_hz=(0.1, 0.3),
    scan_rate_hz=(0.02, 0.08),
    look_down_deg=(20.0, 35.0),
    nod_rate_hz=(0.0, 0.015),
    stride_yaw_deg=(1.0, 3.0),
    bob_scale=(0.8, 1.25),
    variability=True,
    wip_drift_mps=(0.01, 0.05),
    wip_turn_deg_per_step=(-0.45, 0.45),
)

#: The registered populations, by name.
POPULATIONS: Registry[Population] = Registry("population", kind=Population, also="a Population")
for _p in (
    Population("idealised", "no head behaviour, no variability: the idealised scripted user"),
    Population(
        "human",
        "reaction delay, turn overshoot and cadence variation; head straight",
        variability=True,
    ),
    Population(
        "typical",
        "looks at the goal and at what is near, down at the hand; occasional looks around and nods",
        **_TYPICAL_HEAD,
    ),
    Population(
        "gaze_scanners",
        "head-movers who look around often and widely",
        **{
            **_TYPICAL_HEAD,
            "eye_range_deg": (5.0, 12.0),
            "scan_rate_hz": (0.06, 0.12),
            "scan_amplitude_deg": (20.0, 50.0),
        },
    ),
    Population(
        "nodders",
        "typical gaze with frequent nod bouts",
        **{**_TYPICAL_HEAD, "nod_rate_hz": (0.1, 0.25)},
    ),
):
    POPULATIONS.register(_p.name, _p, _p.description)
del _p


def population_names() -> tuple[str, ...]:
    """The registered population names."""
    return tuple(POPULATIONS.names())


def get_population(name: str | Population, field: str = "population") -> Population:
    """The population ``name`` (a registered name or a :class:`Population`).

    Raises:
        ValueError: an unknown name, naming ``field`` and the registered names.
    """
    return POPULATIONS.get(name, field=field)
