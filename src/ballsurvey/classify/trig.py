"""sin, cos and atan2 in plain arithmetic, for loops that LLVM runs in SIMD lanes.

numba calls libm's `sin`, `cos` and `atan2` one value at a time (its vectorised maths, SVML, is
not in pip's llvmlite), and a loop with a call in it is not vectorised. These are branch-free
(every choice is a select), so a loop over them is; a value costs a few dozen multiply-adds.

* `sincos(x)`: x = k pi/2 + r with |r| <= pi/4 (Cody-Waite: pi/2 in three parts of 33 bits, so
  k times each part is exact for |k| < 2^20, |x| < 1.6e6); sin r and cos r by their Taylor
  series to r^17 and r^18 (the first terms left out are below 1e-19 of the result on
  |r| <= pi/4), Horner's rule; the quadrant k mod 4 picks and signs them.
* `sincos_shift(sin m, cos m, d)`: sin and cos of m + d for |d| <= pi/2 by the angle sum, with
  sin d and cos d - 1 by their series: the value varies smoothly with d, to half a unit in the
  last place (a function of theta summed near a turning point stays as smooth as its terms).
* `atan2(y, x)`: t = min(|x|, |y|) / max(|x|, |y|) in [0, 1]; where t > tan(pi/12), atan t =
  pi/6 + atan((t sqrt 3 - 1) / (t + sqrt 3)), an argument again within tan(pi/12) = 0.268;
  atan by its Taylor series to t^27 (the first term left out is below 1e-17 of the result);
  then the octant: pi/2 - a where |y| > |x|, pi - a where x < 0, the sign of y.

Within a few units in the last place of libm's (tests/test_trig.py against numpy). For |x| above
1.6e6 `sincos` loses accuracy: its callers pass tilts (|theta| <= pi/2) and headings that turn
by tens of radians at most.
"""
from __future__ import annotations

import math
from decimal import Decimal, localcontext

from .._jit import njit

jit = njit(cache=True, nogil=True, error_model="numpy", inline="always")  # stamped cache


def _split_half_pi(bits: int = 33) -> tuple[float, float, float]:
    """pi/2 as hi + mid + lo, hi and mid of `bits` significant bits (k * each exact for small
    k), from 60 digits of pi."""
    with localcontext() as ctx:  # the process's own decimal context is left as it is
        ctx.prec = 80
        rest = Decimal("3.14159265358979323846264338327950288419716939937510582097494459") / 2
        parts = []
        for _ in range(2):
            e = math.frexp(float(rest))[1]
            q = Decimal(2) ** (bits - e)
            part = Decimal(int(rest * q)) / q  # rest truncated to `bits` bits
            parts.append(float(part))
            rest -= part
        parts.append(float(rest))
    return tuple(parts)


PIO2_HI, PIO2_MID, PIO2_LO = _split_half_pi()
TWO_OVER_PI = 2.0 / math.pi
#: Taylor coefficients: sin d = d + d^3 (T1 + d^2 (T2 + ...)), cos d - 1 = d^2 (K1 + d^2 (...));
#: `sincos` (|r| <= pi/4) takes the first 8 and 9 of them, `sincos_shift` (|d| <= pi/2) all 11
T1, T2, T3, T4, T5, T6, T7, T8, T9, T10, T11 = (
    (-1.0) ** n / math.factorial(2 * n + 1) for n in range(1, 12))
K1, K2, K3, K4, K5, K6, K7, K8, K9, K10, K11 = (
    (-1.0) ** n / math.factorial(2 * n) for n in range(1, 12))
#: atan t = t + t^3 (A1 + t^2 (A2 + ...)) on |t| <= tan(pi/12)
A1, A2, A3, A4, A5, A6, A7, A8, A9, A10, A11, A12, A13 = (
    (-1.0) ** n / (2 * n + 1) for n in range(1, 14))
TAN_PI_12 = 2.0 - math.sqrt(3.0)
SQRT3 = math.sqrt(3.0)


@jit
def sincos(x):
    """(sin x, cos x), branch-free (module docstring)."""
    k = math.floor(x * TWO_OVER_PI + 0.5)
    r = ((x - k * PIO2_HI) - k * PIO2_MID) - k * PIO2_LO
    z = r * r
    p = T5 + z * (T6 + z * (T7 + z * T8))
    s = r + r * z * (T1 + z * (T2 + z * (T3 + z * (T4 + z * p))))
    p = K5 + z * (K6 + z * (K7 + z * (K8 + z * K9)))
    c = 1.0 + z * (K1 + z * (K2 + z * (K3 + z * (K4 + z * p))))
    q = k - 4.0 * math.floor(0.25 * k)  # k mod 4, 0..3
    odd = (q == 1.0) | (q == 3.0)
    sv = c if odd else s
    cv = s if odd else c
    sv = -sv if q >= 2.0 else sv
    cv = -cv if (q == 1.0) | (q == 2.0) else cv
    return sv, cv


@jit
def sincos_shift(sm, cm, d):
    """(sin(m + d), cos(m + d)) from sin m, cos m and |d| <= pi/2, branch-free: sin d and
    cos d - 1 by their Taylor series to d^23 and d^22 (the first terms left out are below 1e-20
    on |d| <= pi/2), added to sin m and cos m last, so that the result's error is that of the
    last addition (half a unit in the last place) and a value varies smoothly with d: the
    rounding of a function of theta near a turning point is not noisier than its terms'."""
    z = d * d
    p = T7 + z * (T8 + z * (T9 + z * (T10 + z * T11)))
    sd = d + d * z * (T1 + z * (T2 + z * (T3 + z * (T4 + z * (T5 + z * (T6 + z * p))))))
    p = K7 + z * (K8 + z * (K9 + z * (K10 + z * K11)))
    cd1 = z * (K1 + z * (K2 + z * (K3 + z * (K4 + z * (K5 + z * (K6 + z * p))))))
    return sm + (sm * cd1 + cm * sd), cm + (cm * cd1 - sm * sd)


@jit
def atan2(y, x):
    """The angle of (x, y) in [-pi, pi], branch-free (module docstring); 0 at the origin."""
    ax, ay = abs(x), abs(y)
    big, small = max(ax, ay), min(ax, ay)
    t = small / big if big > 0.0 else 0.0
    far = t > TAN_PI_12
    t = (t * SQRT3 - 1.0) / (t + SQRT3) if far else t
    z = t * t
    p = A12 + z * A13
    p = A10 + z * (A11 + z * p)
    p = A7 + z * (A8 + z * (A9 + z * p))
    p = A4 + z * (A5 + z * (A6 + z * p))
    a = t + t * z * (A1 + z * (A2 + z * (A3 + z * p)))
    a = a + math.pi / 6.0 if far else a
    a = 0.5 * math.pi - a if ay > ax else a
    a = math.pi - a if x < 0.0 else a
    return -a if y < 0.0 else a
