"""Every compiled kernel gives the numbers of its uncompiled Python source (its ``py_func``).

The cases live in ``tests/kernel_cases/`` (one module per algorithm family); each is played
compiled and under :func:`estimators.kernels.python_reference`. Ground truth (RMSE against the
truth, closed forms, reference libraries) is the business of each algorithm's own tests.
"""

import importlib
import pkgutil

import kernel_cases
import numpy as np
import pytest

from estimators.kernels import python_reference

CASES = {}
for module in pkgutil.iter_modules(kernel_cases.__path__):
    found = importlib.import_module(f"kernel_cases.{module.name}").CASES
    assert not set(found) & set(CASES), f"kernel case names repeat in {module.name}"
    CASES.update(found)


def _arrays(out) -> dict[str, np.ndarray]:
    if isinstance(out, dict):
        return {k: np.asarray(v) for k, v in out.items()}
    return {"out": np.asarray(out)}


@pytest.mark.parametrize("name", sorted(CASES))
def test_compiled_equals_python_source(name):
    compiled = _arrays(CASES[name]())
    with python_reference():
        python = _arrays(CASES[name]())
    assert compiled.keys() == python.keys()
    for key in compiled:
        np.testing.assert_allclose(
            compiled[key],
            python[key],
            rtol=1e-12,
            atol=1e-12,
            equal_nan=True,
            err_msg=f"{name}: {key}",
        )
