"""Helpers shared by the reachability tests: the fine reference runs and the re-check's import closure."""

from __future__ import annotations

import ast
import itertools
import pathlib
from collections.abc import Callable, Sequence

import numpy as np
import pytest
from scipy.integrate import solve_ivp

REACH = pathlib.Path(__file__).resolve().parents[3] / "analysis" / "reach"


def _fine_runs(rhs: Callable, lo: Sequence[float], hi: Sequence[float], horizon: float, count: int, seed: int,
               every: float) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    corners = np.array(list(itertools.product(*zip(lo, hi))), dtype=float)
    starts = np.vstack([corners, rng.uniform(lo, hi, size=(count, len(lo)))])
    t_eval = np.arange(0.0, horizon + 1e-12, every)
    times, points = [], []
    for x0 in starts:
        sol = solve_ivp(rhs, (0.0, horizon), x0, method="DOP853", t_eval=t_eval, rtol=1e-10, atol=1e-12)
        assert sol.success
        times.append(sol.t)
        points.append(sol.y.T)
    return np.concatenate(times), np.vstack(points)


@pytest.fixture
def fine_runs() -> Callable[..., tuple[np.ndarray, np.ndarray]]:
    """``fine_runs(rhs, lo, hi, horizon, count, seed, every) -> (times (m,), points (m, n))``: DOP853 runs (rtol
    1e-10, atol 1e-12; no reachability code) from the corners of the box ``[lo, hi]`` and ``count`` seeded uniform
    starts in it, sampled every ``every`` s over ``[0, horizon]``."""
    return _fine_runs


def _relative_imports(start: str) -> set[str]:
    seen, todo = set(), [start]
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        for node in ast.walk(ast.parse((REACH / f"{name}.py").read_text())):
            if isinstance(node, ast.ImportFrom) and node.level == 1 and node.module:
                todo.append(node.module)
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("analysis.reach."):
                todo.append(node.module.split(".")[-1])
    return seen


@pytest.fixture
def reach_imports() -> Callable[[str], set[str]]:
    """``reach_imports(module) -> set``: the modules of ``analysis.reach`` that ``module`` imports, directly or
    through them (relative or absolute ``from`` imports, read from the source)."""
    return _relative_imports
