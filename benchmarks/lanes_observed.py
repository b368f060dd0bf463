"""The DOP853 lane kernels on 256 full launches around the square (T = 20 s, rtol 1e-9): the bare
kernel, and the observed one (the `dop853` map method, the step observer on each accepted step),
so that what the steps cost and what the observer costs can be told apart. Needs only ballsurvey:

    python benchmarks/lanes_observed.py [--launches 256] [--repeats 3]
"""
from __future__ import annotations

import argparse

import numba

from ballsurvey.accuracy import best_of, square_launches
from ballsurvey.classify.observer import N_OBS
from ballsurvey.compose import STEP_OBSERVER
from ballsurvey.integrate.lanes import integrate_lanes, integrate_observed


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--launches", type=int, default=256)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    y0, p, T, _ = square_launches(args.launches)
    runs = {"bare kernel": lambda: integrate_lanes(y0, p, T, 1e-9),
            "observed on each step": lambda: integrate_observed(
                y0, p, T, 1e-9, observer=STEP_OBSERVER, n_slots=N_OBS)}
    print(f"DOP853 lanes: {args.launches} launches around the square, T = 20 s, rtol 1e-9, "
          f"{numba.get_num_threads()} threads, best of {args.repeats}")
    for name, run in runs.items():
        run()  # compile or load from the cache
        _, t = best_of(run, args.repeats)
        print(f"  {name:34s} {args.launches / t:8.0f} launches/s")


if __name__ == "__main__":
    main()
