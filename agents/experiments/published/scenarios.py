"""The published findings the testbed reproduces, each as a scenario written down before it is
run on the reporting seeds: what the study found, the task, the users, the techniques compared,
the metric, the expected direction and the test. :mod:`agents.experiments.published.run` plays
them (``vrloco experiment published``).

Seeds. The details below (episodes, margins' rule, users) were chosen on the development seeds
:data:`DEV_SEEDS`; every reported figure comes from the reporting seeds :data:`REPORT_SEEDS`,
where nothing is tuned. An equivalence margin is a rule stated
here and evaluated on the development seeds (so the reporting seeds do not set their own bar).

Tests. ``difference``: the two-sided Wilcoxon signed-rank test of the paired per-episode
differences (:func:`agents.benchmark.paired.wilcoxon_p`) at :data:`ALPHA`; reproduced when it
rejects in the expected direction. ``equivalence``: two one-sided t-tests of the paired
differences against the margin (TOST, Schuirmann, J. Pharmacokinet. Biopharm. 15(6), 1987) at
:data:`ALPHA`; reproduced when both reject (the 90 % interval of the mean difference lies inside
the margin), never from a failed difference test. ``range``: the metric's mean, with its 95 %
bootstrap interval, against a published range; reproduced when the interval overlaps the range.
The effect is always B minus A (the second technique, or condition, minus the first), with a
95 % bootstrap interval of the mean paired difference.

Users: the goal seeker with the ``typical`` population's variability and head behaviour
(``goal_seeker+typical``, ``population="typical"``): the people of the calibrated population,
each study's participants. Completion time counts a failed episode as the full horizon (60 s),
so a technique cannot look fast by failing.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["ALPHA", "DEV_SEEDS", "FINDINGS", "REPORT_SEEDS", "Finding"]

#: Significance level of every test.
ALPHA = 0.05
#: Development seeds: where the scenarios' details were chosen and margins are evaluated.
DEV_SEEDS = tuple(range(1000, 1020))
#: Reporting seeds: seeds that neither these scenarios nor the development of their techniques
#: and of the goal seeker's adaptation to them played (those used seeds 0-7 and
#: :data:`DEV_SEEDS`).
REPORT_SEEDS = tuple(range(2000, 2060))


@dataclass(frozen=True)
class Finding:
    """One published finding and the scenario that tests it.

    Attributes:
        id: the finding's id (the JSON's ``id``).
        source: the study (authors, venue, year).
        study_n: participants in the study (None: not given in the abstract read).
        claim: what the study found, in a line.
        task: the task played (None: not testable here).
        techniques: (A, B), compared on the same episodes; for a ``range`` test, A alone.
        population: the env's population (the users' head behaviour).
        policy: the simulated users.
        metric: the per-episode metric (:func:`agents.experiments.published.run.metric_values`).
        expected: ``"B < A"``, ``"B > A"``, ``"B = A"`` (equivalent) or ``"in [lo, hi]"``.
        test: ``"difference"``, ``"equivalence"`` or ``"range"``.
        margin: the equivalence margin's rule (``"10% of A's mean on the development seeds"``).
        margin_fraction: that fraction.
        range: (lo, hi) of a ``range`` test.
        conditions: (A, B) populations instead of techniques, for a finding that compares users
            (the same technique, ``techniques[0]``, under both).
        untestable: why the testbed cannot test it (None: it can).
    """

    id: str
    source: str
    study_n: int | None
    claim: str
    task: str | None
    techniques: tuple[str, ...] = ()
    population: str | None = "typical"
    policy: str = "goal_seeker+typical"
    metric: str = "completion_time_s"
    expected: str = ""
    test: str = ""
    margin: str = ""
    margin_fraction: float = 0.0
    range: tuple[float, float] | None = None
    conditions: tuple[str | None, ...] = ()
    untestable: str | None = None

    @property
    def scenario(self) -> str:
        """The scenario in a line (the JSON's ``scenario``)."""
        if self.untestable is not None:
            return "not testable here"
        what = " vs ".join(self.techniques)
        if self.conditions:
            names = [c or "idealised" for c in self.conditions]
            what = f"{self.techniques[0]}: {' vs '.join(names)} users"
        return f"{self.task}, {self.policy}, {what}, {self.metric}"


FINDINGS: tuple[Finding, ...] = (
    Finding(
        id="tregillus2017_head_tilt",
        source="Tregillus, Al Zayer & Folmer, CHI 2017",
        study_n=24,
        claim="head-tilt locomotion was significantly faster than walking in place",
        task="avoid",
        techniques=("zhang2021", "head_tilt"),
        expected="B < A",
        test="difference",
    ),
    Finding(
        id="tregillus2016_vr_step",
        source="Tregillus & Folmer, CHI 2016 (VR-STEP)",
        study_n=18,
        claim="head-IMU walking in place performed no differently from look-down-to-move",
        task="approach",
        techniques=("zhang2021", "look_down_to_move"),
        expected="B = A",
        test="equivalence",
        margin="10% of A's mean completion time on the development seeds",
        margin_fraction=0.10,
    ),
    Finding(
        id="lee2018_steps",
        source="Lee, Ahn & Hwang, Sensors 2018",
        study_n=9,
        claim="HMD walking in place detected 99.32% of steps regardless of head tilt",
        task="approach",
        techniques=("lee2018_steps",),
        conditions=(None, "nodders"),
        policy="goal_seeker",
        metric="step_accuracy",
        expected="B = A",
        test="equivalence",
        margin="0.02 (two points of step accuracy), a choice: the study's accuracy to one point",
        margin_fraction=0.02,
    ),
    Finding(
        id="lai2020_steering",
        source="Lai, Hu, Segismundo, Phadke & McMahan, 2020",
        study_n=None,
        claim="gaze- and hand-directed steering performed equivalently (TOST)",
        task="avoid",
        techniques=("zhang2021", "hand_steering"),
        expected="B = A",
        test="equivalence",
        margin="10% of A's mean completion time on the development seeds",
        margin_fraction=0.10,
    ),
    Finding(
        id="bruno2017_hip_steering",
        source="Bruno, Sousa, Ferreira, Pereira & Jorge, IJHCS 2017",
        study_n=None,
        claim="hip-directed steering with the angular rule beat the time-based rule",
        task=None,
        untestable=(
            "the testbed steers by the torso's yaw directly; it has neither of the two "
            "mappings from hip rotation to turning that the study compares"
        ),
    ),
    Finding(
        id="wip_stop_latency",
        source="OpenVR-WalkInPlace (practitioner measurements, N of about 1)",
        study_n=1,
        claim="a walking-in-place detector takes about 1/6 to 0.28 s to report a stop",
        task="approach",
        techniques=("lee2018_steps",),
        metric="stop_latency_s",
        expected="in [0.167, 0.28] s",
        test="range",
        range=(1.0 / 6.0, 0.28),
    ),
)
