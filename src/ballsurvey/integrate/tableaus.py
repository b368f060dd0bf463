"""Explicit Runge-Kutta methods as data (Butcher tableaus), driven by one stepper.

As in scipy's integrate/_ivp/rk.py, a method is its coefficients: `a` (stage matrix, strictly lower
triangular), `b` (weights), `c` (nodes) and its order.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Tableau:
    name: str
    order: int
    a: np.ndarray
    b: np.ndarray
    c: np.ndarray

    @property
    def stages(self) -> int:
        return len(self.b)


def _t(name, order, a, b):
    a = np.array(a, dtype=np.float64)
    return Tableau(name, order, a, np.array(b, dtype=np.float64), a.sum(axis=1))


RK4 = _t("rk4", 4,
         [[0, 0, 0, 0], [0.5, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, 1, 0]],
         [1 / 6, 1 / 3, 1 / 3, 1 / 6])
RK38 = _t("rk38", 4,
          [[0, 0, 0, 0], [1 / 3, 0, 0, 0], [-1 / 3, 1, 0, 0], [1, -1, 1, 0]],
          [1 / 8, 3 / 8, 3 / 8, 1 / 8])
HEUN = _t("heun", 2, [[0, 0], [1, 0]], [0.5, 0.5])
SSPRK3 = _t("ssprk3", 3,
            [[0, 0, 0], [1, 0, 0], [0.25, 0.25, 0]],
            [1 / 6, 1 / 6, 2 / 3])

#: fixed-step methods selectable by name in specs and `simulate`
FIXED_STEP = {t.name: t for t in (RK4, RK38, SSPRK3, HEUN)}
