"""The benchmark: simulated users x tasks x techniques over seeded episodes (``vrloco benchmark``).

:mod:`agents.benchmark.run` runs a grid (:func:`run_benchmark`); the grid and its cells
(:mod:`~agents.benchmark.grid`), the physical-room conditions (:mod:`~agents.benchmark.conditions`)
and the policies (:mod:`~agents.benchmark.policies`, :mod:`~agents.benchmark.variability`) say
what runs; the episodes (:mod:`~agents.benchmark.episodes`) are played in jobs
(:mod:`~agents.benchmark.jobs`, :mod:`~agents.benchmark.backends`,
:mod:`~agents.benchmark.warm_start`) and kept for resuming (:mod:`~agents.benchmark.resume`), one
run per output folder (:mod:`~agents.benchmark.run_folder`); their metrics
(:mod:`~agents.benchmark.metrics` and the measures it uses) are compared
(:mod:`~agents.benchmark.paired`, :mod:`~agents.benchmark.discrimination`) and written
(:mod:`~agents.benchmark.outputs`, :mod:`~agents.benchmark.figures`,
:mod:`~agents.benchmark.report`).
"""

from agents.benchmark.run import (
    BASELINE_TECHNIQUE,
    ROW_KEYS,
    check_policy_name,
    run_benchmark,
    show_table,
    step_window,
)

__all__ = [
    "BASELINE_TECHNIQUE",
    "ROW_KEYS",
    "check_policy_name",
    "run_benchmark",
    "show_table",
    "step_window",
]
