"""A synthetic measured track to try `ballsurvey fit` on: the paper's square (Fig. 12a: theta0 =
-5 deg, chidot0 = 4.05 rad/s, phidot0 = -3 rad/s, at rest in theta), its centre of mass filmed
from above at 30 frames/s for 3 s, each position with 0.2 mm of Gaussian tracking noise.

    python examples/make_track.py                  # writes examples/track-square.csv
    ballsurvey fit examples/track-square.csv -o fit.png

The fit should find that launch again, within its stated uncertainties, and call it a square.
"""
from pathlib import Path

import numpy as np

import ballsurvey

FPS, SECONDS, NOISE_M, SEED = 30, 3.0, 2e-4, 12
OUT = Path(__file__).with_name("track-square.csv")


def main(out: Path = OUT) -> Path:
    frames = int(FPS * SECONDS)
    ds = ballsurvey.simulate(-5.0, 0.0, 4.05, -3.0, T=frames / FPS, n_out=frames + 1)
    rng = np.random.default_rng(SEED)
    t = ds.time.values
    x = ds.x.values + rng.normal(0.0, NOISE_M, t.size)
    y = ds.y.values + rng.normal(0.0, NOISE_M, t.size)
    rows = "\n".join(f"{a:.5f},{b:.6f},{c:.6f}" for a, b, c in zip(t, x, y))
    out.write_text("t,x,y\n" + rows + "\n")
    return out


if __name__ == "__main__":
    print(f"wrote {main()}")
