"""How many evaluations the quadrature kernel's turning-point search makes: for a random sample
of the headline map's launches at rest in theta, the far turning point (`classify.cycle`'s
`_turning_point`, run as Python over the jitted F so each call is counted), with the number
of evaluations of F alone (bracketing) and of F with F' (Newton's method in `_root`):

    python benchmarks/turning_points.py [--launches 3000] [--seed 1]

Prints the mean and the largest of each, and the distribution of the second.
"""
from __future__ import annotations

import argparse
import collections
import math

import numpy as np

from ballsurvey.bench import headline_spec
from ballsurvey.classify import cycle
from ballsurvey.compose import launch_arrays
from ballsurvey.physics.euler import accelerations, jellett, kinetic, routh
from ballsurvey.sweep.plan import launch_table
from ballsurvey.sweep.spec import load_spec


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--launches", type=int, default=3000)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    n = 100
    spec = load_spec("headline.toml", text=headline_spec(n, method="quadrature", out="x.nc"))
    y0, params, _, _ = launch_arrays(launch_table(spec, 0, n ** 3))
    pick = np.random.default_rng(args.seed).choice(n ** 3, args.launches, replace=False)
    count = collections.Counter()
    rates, f_df = cycle._rates, cycle._F_dF
    f_df(0.3, cycle._constants(1.0, 0.1, 0.1, 0.3, 0.4, 0.5))  # compiled before _rates is patched

    def counted_rates(*a):
        count["F"] += 1
        return rates(*a)

    def counted_f_df(*a):
        count["F_dF"] += 1
        return f_df(*a)
    cycle._rates, cycle._F_dF, cycle._root = counted_rates, counted_f_df, cycle._root.py_func
    probes, newton = collections.Counter(), collections.Counter()
    for i in pick:
        th0, thd0, chd0, phd0 = y0[2, i], y0[5, i], y0[6, i], y0[7, i]
        c, A, B = params[:, i]
        a = (math.sin(th0), math.cos(th0), thd0, chd0, phd0, c, A, B)
        kin = kinetic(*a)
        thdd0 = accelerations(*a)[0]
        if abs(thdd0) < 1e-8:
            continue  # steady: the integrator's
        d = 1.0 if thdd0 > 0.0 else -1.0
        count.clear()
        root = cycle._turning_point.py_func(
            th0 + d * cycle.START_OFFSET, d, th0, 2.0 * abs(thdd0) * a[1] ** 2,
            cycle.ROOT_NOISE * 2.2e-16 * (kin + c * abs(a[0])),
            cycle._constants(kin - c * a[0], jellett(*a), routh(*a), c, A, B))[0]
        if math.isfinite(root):
            probes[count["F"]] += 1
            newton[count["F_dF"]] += 1

    def mean(h):
        return sum(k * v for k, v in h.items()) / sum(h.values())
    print(f"{sum(newton.values())} of {args.launches} headline launches at rest in theta have "
          "a far turning point (the others reach the vertical or are steady)")
    print(f"  evaluations of F while bracketing: mean {mean(probes):.2f}, at most {max(probes)}")
    print(f"  evaluations of F and F' (Newton): mean {mean(newton):.2f}, at most {max(newton)}")
    print("  distribution of the second:", dict(sorted(newton.items())))


if __name__ == "__main__":
    main()
