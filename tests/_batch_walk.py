"""Finding what in a batch is still sized for its users: the check behind ``take_users``."""

import numpy as np


def sized(obj, n: int, path: str = "env", seen: set | None = None) -> list[str]:
    """Paths of the arrays and lists reachable from ``obj`` whose first axis has ``n`` items
    (the package's objects only)."""
    seen = set() if seen is None else seen
    if id(obj) in seen:
        return []
    seen.add(id(obj))
    if isinstance(obj, np.ndarray):
        return [path] if obj.ndim and obj.shape[0] == n else []
    if isinstance(obj, list | tuple):
        here = [path] if len(obj) == n and not hasattr(obj, "_fields") else []
        return here + [p for i, x in enumerate(obj) for p in sized(x, n, f"{path}[{i}]", seen)]
    if isinstance(obj, dict):
        return [p for k, v in obj.items() for p in sized(v, n, f"{path}[{k!r}]", seen)]
    if not type(obj).__module__.startswith(("vrloco_env", "estimators", "agents", "types")):
        return []
    attrs = getattr(obj, "__dict__", {})
    return [p for k, v in attrs.items() for p in sized(v, n, f"{path}.{k}", seen)]
