"""`ballsurvey animate`'s writing, side by side: the same frames of one launch written to a GIF by
matplotlib's own route (`animation(ds).save(..., PillowWriter)`: every frame laid out and drawn
whole by savefig) and by `write_animation` (the still parts drawn once, each frame drawing only
the moving parts onto that background). Both runs get the same trajectory; the script prints
both times, their ratio, and how far the two routes' frames differ before the GIF's palette
(largest difference of a pixel's channel, 0..255, and the share of pixels that differ at all).
Needs only ballsurvey:

    python benchmarks/animate_render.py [--T 3] [--repeats 1]

The default is the README's animate command: the paper's square (theta0 = -5 deg, chidot0 =
4.05, phidot0 = -3 rad/s), 3 s of motion at half speed, 20 frames a second: 121 frames.
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from matplotlib.animation import PillowWriter
from PIL import Image

import ballsurvey
from ballsurvey.animate import DPI, FPS, animation, frame_count, frames, write_animation


def _old(ds, out):
    writer = PillowWriter(fps=FPS)
    animation(ds).save(out, writer=writer, dpi=DPI)
    return writer._frames  # the RGB frames it wrote


def _new(ds, out):
    write_animation(ds, out)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--T", type=float, default=3.0, help="seconds of motion (default 3)")
    ap.add_argument("--repeats", type=int, default=1, help="runs of each, best kept")
    args = ap.parse_args()
    dt = 1e-3
    ds = ballsurvey.simulate(-5.0, 0.0, 4.05, -3.0, T=args.T, dt=dt,
                             n_out=int(round(args.T / dt)) + 1)
    n = frame_count(float(ds.time[-1] - ds.time[0]))
    with tempfile.TemporaryDirectory() as tmp:
        old, new = Path(tmp, "old.gif"), Path(tmp, "new.gif")
        times = {"matplotlib savefig per frame": [], "write_animation (background once)": []}
        for _ in range(args.repeats):  # in turns: the machine's noise hits both alike
            for spent, fn, out in zip(times.values(), (_old, _new), (old, new)):
                t0 = time.perf_counter()
                fn(ds, out)
                spent.append(time.perf_counter() - t0)
        # the frames as drawn, before the GIF's palette (each frame's own): one pass of each,
        # not timed
        a = [np.asarray(im, dtype=np.int16) for im in _old(ds, old)]
        b = [np.asarray(f, dtype=np.int16)[..., :3] for f in frames(ds)]
        for path in (old, new):
            with Image.open(path) as im:
                assert im.n_frames == n, (path, im.n_frames, n)
        assert len(a) == len(b) == n, (len(a), len(b), n)
        diff = max(int(np.abs(x - y).max()) for x, y in zip(a, b))
        share = np.mean([np.any(x != y, axis=-1).mean() for x, y in zip(a, b)])
    best = {name: min(v) for name, v in times.items()}
    print(f"{n} frames of {a[0].shape[1]} x {a[0].shape[0]} pixels, the paper's square, "
          f"T = {args.T:g} s (best of {args.repeats})")
    for name, s in best.items():
        print(f"  {name:36s} {s:7.2f} s  ({s / n * 1e3:.0f} ms a frame)")
    old_s, new_s = best.values()
    print(f"  ratio {old_s / new_s:.1f}x; frames differ by at most {diff} of 255 in a channel, "
          f"{share:.2%} of pixels differ")


if __name__ == "__main__":
    main()
