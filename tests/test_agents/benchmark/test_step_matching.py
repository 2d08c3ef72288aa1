"""Step F1 (agents.benchmark.step_matching.step_f1): one-to-one matching of detected and true step
times within a tolerance, a maximum matching."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import maximum_bipartite_matching

from agents.benchmark.step_matching import step_f1


def test_step_f1_matching():
    truth = np.array([1.0, 2.0, 3.0, 4.0])
    assert step_f1(truth + 0.1, truth) == (1.0, 1.0, 1.0)
    p, r, f = step_f1(truth + 0.25, truth)
    assert (p, r, f) == (0.0, 0.0, 0.0)
    # Two detections around one true step: only one may match it.
    p, r, f = step_f1([1.95, 2.05], [2.0])
    assert (p, r) == (0.5, 1.0)
    # One-to-one needs the global assignment: greedy nearest would pair 1.15 with 1.1 and
    # leave 0.95 unmatched.
    p, r, f = step_f1([0.95, 1.15], [1.1, 1.3])
    assert (p, r) == (1.0, 1.0)
    assert step_f1([], []) == (1.0, 1.0, 1.0)
    assert step_f1([], [1.0]) == (1.0, 0.0, 0.0)
    assert step_f1([1.0], []) == (0.0, 1.0, 0.0)
    with pytest.raises(ValueError, match="tol"):
        step_f1([1.0], [1.0], tol=0.0)
    with pytest.raises(ValueError, match="finite"):
        step_f1([np.nan], [1.0])


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(0.0, 5.0), max_size=12),
    st.lists(st.floats(0.0, 5.0), max_size=12),
)
def test_step_f1_is_a_maximum_matching(det, tru):
    """The matched count equals a maximum bipartite matching of the pairs within tol."""
    det, tru = np.asarray(det), np.asarray(tru)
    p, r, _ = step_f1(det, tru, tol=0.2)
    matched = round(p * det.size) if det.size else round(r * tru.size) if tru.size else 0
    if det.size and tru.size:
        graph = csr_matrix((np.abs(det[:, None] - tru[None, :]) <= 0.2).astype(np.int8))
        best = int(np.count_nonzero(maximum_bipartite_matching(graph, perm_type="column") >= 0))
    else:
        best = 0
    assert matched == best
