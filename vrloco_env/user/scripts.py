"""Zhang 2021's scripted motions: the names (:data:`SCRIPTS`), the intent sequence of each
(:func:`script_intents`) and a run of one by every user of a batch (:func:`run_script`)."""

from __future__ import annotations

import numpy as np

from vrloco_env.batch_rng import BatchRng
from vrloco_env.user.intent import Intent
from vrloco_env.user.motion_params import MotionParams
from vrloco_env.user.motion_records import MotionRecord

__all__ = ["SCRIPTS", "run_script", "script_intents"]

SCRIPTS = (
    "stand",
    "serpentine",
    "pitch",
    "shake",
    "spin",
    "backward",
    "straight",
    "avoid",
    "stand_step_turn",
)


def script_intents(
    name: str,
    params: MotionParams | None = None,
    cadence: float = 1.7,
    duration_s: float | None = None,
) -> list[Intent]:
    """Intent sequence of one of Zhang 2021's experiments (one :class:`Intent` per control step).

    Args:
        name: one of :data:`SCRIPTS`:
            ``stand`` still; ``serpentine`` head yaw left-right (±40 deg, 0.4 Hz) standing;
            ``pitch`` nod forward then back (±30 deg, 0.3 Hz); ``shake`` roll left-right
            (±25 deg, 0.5 Hz); ``spin`` a full turn in place (stepping, 45 deg/s for 8 s);
            ``backward`` lean back 15 deg while stepping in place; ``straight`` stepping in
            place facing one direction (Fig. 4); ``avoid`` stepping, turn away 45 deg from an
            obstacle, step on, turn back to the original heading, step on (Fig. 5);
            ``stand_step_turn`` stand, step in place, turn while stepping, stand (the demo).
        params: the motion parameters (for the control rate).
        cadence: stepping cadence (steps/s) where the script steps.
        duration_s: total length (s); each script has a sensible default.
    """
    p = params or MotionParams()
    dt = 1.0 / p.control_rate_hz
    z3 = (0.0, 0.0, 0.0)

    def seg(seconds: float, **kw) -> list[Intent]:
        return [Intent(**kw) for _ in range(round(seconds / dt))]

    deg = np.deg2rad
    if name == "stand":
        seq = seg(duration_s or 10.0)
    elif name in ("serpentine", "pitch", "shake"):
        axis = {"serpentine": 0, "pitch": 1, "shake": 2}[name]
        amp = list(z3)
        amp[axis] = deg({"serpentine": 40.0, "pitch": 30.0, "shake": 25.0}[name])
        freq = [{"serpentine": 0.4, "pitch": 0.3, "shake": 0.5}[name]] * 3
        total = duration_s or 20.0
        # The frequency is held throughout, so the head rate stays continuous as the gesture
        # fades in and out.
        seq = (
            seg(2.0, gesture_frequency=tuple(freq))
            + seg(total - 4.0, gesture_amplitude=tuple(amp), gesture_frequency=tuple(freq))
            + seg(2.0, gesture_frequency=tuple(freq))
        )
    elif name == "spin":
        seq = seg(2.0) + seg(8.0, cadence=cadence, turn_rate=deg(45.0)) + seg(2.0)
    elif name == "backward":
        total = duration_s or 16.0
        seq = seg(2.0) + seg(total - 4.0, cadence=cadence, lean=-deg(15.0)) + seg(2.0)
    elif name == "straight":
        total = duration_s or 20.0
        seq = seg(2.0) + seg(total - 4.0, cadence=cadence) + seg(2.0)
    elif name == "avoid":
        turn = deg(45.0)
        seq = (
            seg(2.0)
            + seg(5.0, cadence=cadence)
            + seg(1.5, cadence=cadence, turn_rate=turn / 1.5)
            + seg(4.0, cadence=cadence)
            + seg(1.5, cadence=cadence, turn_rate=-turn / 1.5)
            + seg(6.0, cadence=cadence)
            + seg(2.0)
        )
    elif name == "stand_step_turn":
        seq = (
            seg(3.0)
            + seg(5.0, cadence=cadence)
            + seg(4.0, cadence=cadence, turn_rate=deg(45.0))
            + seg(3.0, cadence=cadence)
            + seg(3.0)
        )
    else:
        raise ValueError(f"unknown motion script {name!r}; choose one of {', '.join(SCRIPTS)}")
    return seq


def run_script(
    name: str, rng: BatchRng, params: MotionParams | None = None, yaw: float = 0.0, **kwargs
) -> MotionRecord:
    """Run a scripted sequence (see :func:`script_intents`) for every user of ``rng``."""
    from vrloco_env.user.motion import UserMotion  # motion re-exports this module's names

    p = params or MotionParams()
    motion = UserMotion(p, rng)
    motion.reset(yaw=yaw)
    chunks = [motion.advance(i) for i in script_intents(name, p, **kwargs)]
    return MotionRecord.concatenate(chunks)
