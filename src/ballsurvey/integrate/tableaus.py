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


@dataclass(frozen=True)
class EmbeddedTableau:
    """An embedded pair: `b` gives the solution (order `order`), `b - b_err` the error estimate
    (order `error_order`)."""

    name: str
    order: int
    error_order: int
    a: np.ndarray
    b: np.ndarray
    b_err: np.ndarray  # b - b_hat: weights of the error estimate
    c: np.ndarray
    #: dense output: y(t + x h) = y + h sum_s k_s sum_j dense[s, j] x^(j+1), 0 <= x <= 1, with
    #: k_s the stages and the last one f(y_new) (FSAL)
    dense: np.ndarray

    @property
    def error_exponent(self) -> float:
        """The step-size rule's exponent, -1 / (error_order + 1) (as scipy's rk.py)."""
        return -1.0 / (self.error_order + 1)


def _dopri5() -> EmbeddedTableau:
    a = np.zeros((7, 7))
    a[1, 0] = 1 / 5
    a[2, :2] = [3 / 40, 9 / 40]
    a[3, :3] = [44 / 45, -56 / 15, 32 / 9]
    a[4, :4] = [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729]
    a[5, :5] = [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656]
    a[6, :6] = [35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84]
    b = a[6].copy()
    b_hat = np.array([5179 / 57600, 0, 7571 / 16695, 393 / 640, -92097 / 339200, 187 / 2100,
                      1 / 40])
    # Shampine's quartic continuous extension (Hairer, Norsett & Wanner; scipy's RK45.P)
    dense = np.array([
        [1, -8048581381 / 2820520608, 8663915743 / 2820520608, -12715105075 / 11282082432],
        [0, 0, 0, 0],
        [0, 131558114200 / 32700410799, -68118460800 / 10900136933,
         87487479700 / 32700410799],
        [0, -1754552775 / 470086768, 14199869525 / 1410260304, -10690763975 / 1880347072],
        [0, 127303824393 / 49829197408, -318862633887 / 49829197408,
         701980252875 / 199316789632],
        [0, -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844],
        [0, 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423]])
    return EmbeddedTableau("dopri5", 5, 4, a, b, b - b_hat, a.sum(axis=1), dense)


#: Dormand-Prince 5(4), FSAL (Hairer, Norsett & Wanner, Solving ODEs I, Table 5.2)
DOPRI5 = _dopri5()
#: adaptive methods selectable by name in specs and `simulate`
ADAPTIVE = {"dopri5": DOPRI5, "adaptive": DOPRI5}


@dataclass(frozen=True)
class LaneTableau:
    """An embedded pair for the SIMD-lane adaptive kernel (`lanes.py`): the solution weights `b`
    (order `order`) and two error estimates, `e5` (order 5) and `e3` (order 3), combined as in
    Hairer's DOP853: err = |h| n5 / sqrt(n * (n5 + 0.01 n3)), n5 and n3 the squared scaled norms
    (Hairer, Norsett & Wanner, Solving ODEs I, 2nd ed., section II.10). A pair with e3 = 0 is the
    plain RMS norm of e5."""

    name: str
    order: int
    error_order: int
    a: np.ndarray
    b: np.ndarray
    e5: np.ndarray
    e3: np.ndarray

    @property
    def stages(self) -> int:
        return len(self.b)

    @property
    def error_exponent(self) -> float:
        return -1.0 / (self.error_order + 1)


# Dormand & Prince's 8(5,3) pair, 12 stages (Hairer, Norsett & Wanner, Solving ODEs I, II.10; the
# coefficients of Hairer's dop853.f, to double precision). The order conditions are checked in
# tests/test_lanes.py, so a misprint here cannot pass.
def _dop853() -> LaneTableau:
    a = np.zeros((12, 12))
    a[1, 0] = 0.05260015195876773
    a[2, 0] = 0.0197250569845379
    a[2, 1] = 0.0591751709536137
    a[3, 0] = 0.02958758547680685
    a[3, 2] = 0.08876275643042054
    a[4, 0] = 0.2413651341592667
    a[4, 2] = -0.8845494793282861
    a[4, 3] = 0.924834003261792
    a[5, 0] = 0.037037037037037035
    a[5, 3] = 0.17082860872947386
    a[5, 4] = 0.12546768756682242
    a[6, 0] = 0.037109375
    a[6, 3] = 0.17025221101954405
    a[6, 4] = 0.06021653898045596
    a[6, 5] = -0.017578125
    a[7, 0] = 0.03709200011850479
    a[7, 3] = 0.17038392571223998
    a[7, 4] = 0.10726203044637328
    a[7, 5] = -0.015319437748624402
    a[7, 6] = 0.008273789163814023
    a[8, 0] = 0.6241109587160757
    a[8, 3] = -3.3608926294469414
    a[8, 4] = -0.868219346841726
    a[8, 5] = 27.59209969944671
    a[8, 6] = 20.154067550477894
    a[8, 7] = -43.48988418106996
    a[9, 0] = 0.47766253643826434
    a[9, 3] = -2.4881146199716677
    a[9, 4] = -0.590290826836843
    a[9, 5] = 21.230051448181193
    a[9, 6] = 15.279233632882423
    a[9, 7] = -33.28821096898486
    a[9, 8] = -0.020331201708508627
    a[10, 0] = -0.9371424300859873
    a[10, 3] = 5.186372428844064
    a[10, 4] = 1.0914373489967295
    a[10, 5] = -8.149787010746927
    a[10, 6] = -18.52006565999696
    a[10, 7] = 22.739487099350505
    a[10, 8] = 2.4936055526796523
    a[10, 9] = -3.0467644718982196
    a[11, 0] = 2.273310147516538
    a[11, 3] = -10.53449546673725
    a[11, 4] = -2.0008720582248625
    a[11, 5] = -17.9589318631188
    a[11, 6] = 27.94888452941996
    a[11, 7] = -2.8589982771350235
    a[11, 8] = -8.87285693353063
    a[11, 9] = 12.360567175794303
    a[11, 10] = 0.6433927460157636
    b = np.zeros(12)
    b[0] = 0.054293734116568765
    b[5] = 4.450312892752409
    b[6] = 1.8915178993145003
    b[7] = -5.801203960010585
    b[8] = 0.3111643669578199
    b[9] = -0.1521609496625161
    b[10] = 0.20136540080403034
    b[11] = 0.04471061572777259
    e5 = np.zeros(12)
    e5[0] = 0.01312004499419488
    e5[5] = -1.2251564463762044
    e5[6] = -0.4957589496572502
    e5[7] = 1.6643771824549864
    e5[8] = -0.35032884874997366
    e5[9] = 0.3341791187130175
    e5[10] = 0.08192320648511571
    e5[11] = -0.022355307863886294
    e3 = np.zeros(12)
    e3[0] = -0.18980075407240762
    e3[5] = 4.450312892752409
    e3[6] = 1.8915178993145003
    e3[7] = -5.801203960010585
    e3[8] = -0.4226823213237919
    e3[9] = -0.1521609496625161
    e3[10] = 0.20136540080403034
    e3[11] = 0.02265179219836082
    return LaneTableau("dop853", 8, 7, a, b, e5, e3)


#: Dormand-Prince 8(5,3)
DOP853 = _dop853()
#: methods of the SIMD-lane adaptive kernel (`lanes.py`)
LANE_ADAPTIVE = {"dop853": DOP853}


def _grouped(coefs) -> list[tuple[float, list[int]]]:
    """Nonzero coefficients (index j -> value) grouped by value, in order of first appearance:
    equal weights multiply one sum (RK4's 1/6 (k0 + k3) + 1/3 (k1 + k2))."""
    groups: dict[float, list[int]] = {}
    for j, w in coefs:
        if w != 0.0:
            groups.setdefault(float(w), []).append(j)
    return list(groups.items())


def _combination(groups, names, q) -> str:
    parts = []
    for (_, js), h in zip(groups, names):
        ks = " + ".join(f"k{j}[{q}]" for j in js)
        parts.append(f"{h} * ({ks})" if len(js) > 1 else f"{h} * {ks}")
    return " + ".join(parts)


def step_constants(tab: Tableau, indent: str) -> str:
    """Python source assigning the step's constants (dt times a coefficient) that
    `stage_source`'s text uses, for a kernel to run once before its step loop: in the loop each
    stage costs one product per distinct coefficient and variable, not one per term plus one for
    dt."""
    lines = []
    for s in range(1, tab.stages):
        for g, (w, _) in enumerate(_grouped(enumerate(tab.a[s, :s]))):
            lines.append(f"dta{s}_{g} = dt * {w!r}")
    for g, (w, _) in enumerate(_grouped(enumerate(tab.b))):
        lines.append(f"dtb{g} = dt * {w!r}")
    return "\n".join(indent + line for line in lines)


def stage_source(tab: Tableau, n_vars: int, indent: str, lane: str = "") -> tuple[str, str]:
    """Python source of one explicit RK step written out from the tableau, for the generated
    kernels (CPU ensemble and CUDA): the stages (`s0` the state tuple, `kJ = fast_rhs(sJ, c, A,
    B)`) and the update of the state variables `r0{lane}` ... (lane: "[i]" for a SIMD row, "" for a
    scalar). Zero coefficients are left out and equal ones share a product, with dt folded into
    the constants of `step_constants` (which the kernel assigns before its loop)."""
    v = range(n_vars)
    stages = [indent + "k0 = fast_rhs(s0, c, A, B)"]
    for s in range(1, tab.stages):
        groups = _grouped(enumerate(tab.a[s, :s]))
        names = [f"dta{s}_{g}" for g in range(len(groups))]
        comps = ", ".join(f"s0[{q}] + ({_combination(groups, names, q)})" for q in v)
        stages.append(f"{indent}s{s} = ({comps})")
        stages.append(f"{indent}k{s} = fast_rhs(s{s}, c, A, B)")
    groups = _grouped(enumerate(tab.b))
    names = [f"dtb{g}" for g in range(len(groups))]
    update = "\n".join(f"{indent}r{q}{lane} = s0[{q}] + ({_combination(groups, names, q)})"
                       for q in v)
    return "\n".join(stages), update
