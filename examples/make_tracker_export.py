"""A track in Tracker's own export layout to try `ballsurvey fit` on, as a lab bench gives it.

Tracker (physlets.org/tracker) File > Export > Data writes a tab-separated text file: a first
line naming the tracked mass, a header line `t	x	y`, and one row per frame, in the units of
its calibration (here cm). Frames where the autotracker lost the ball are blank cells.

The motion is the paper's triangle (Fig. 12b: theta0 = -10 deg, chidot0 = 2.3 rad/s, phidot0 =
-2.5 rad/s, at rest in theta) launched at chi0 = 30 deg from (12, 8) cm in Tracker's axes,
integrated by scipy's DOP853 on the fixed-frame Newton-Euler equations (not the Euler-angle
kernel the fit uses), filmed at 30 frames/s for 3 s with 0.3 mm of Gaussian tracking noise on
each position, and frames 17, 18 and 52 lost.

    python examples/make_tracker_export.py          # writes examples/track-tracker.txt
    ballsurvey fit examples/track-tracker.txt --units cm -o fit.png
"""
from pathlib import Path

from ballsurvey.synthetic import synthetic_track

LAUNCH = dict(theta0_deg=-10.0, thetadot0=0.0, chidot0=2.3, phidot0=-2.5, chi0_deg=30.0,
              x0=0.12, y0=0.08)
FPS, SECONDS, NOISE_M, SEED = 30, 3.0, 3e-4, 7
LOST = (17, 18, 52)
OUT = Path(__file__).with_name("track-tracker.txt")


def main(out: Path = OUT) -> Path:
    tr = synthetic_track(**LAUNCH, T=SECONDS, fps=FPS, noise_m=NOISE_M, seed=SEED)
    rows = []
    for i, (t, x, y) in enumerate(zip(tr["t"], tr["x"] * 100, tr["y"] * 100)):
        cells = ("", "") if i in LOST else (f"{x:.4f}", f"{y:.4f}")
        rows.append("\t".join((f"{t:.4f}",) + cells))
    out.write_text("mass A\nt\tx\ty\n" + "\n".join(rows) + "\n")
    return out


if __name__ == "__main__":
    print(f"wrote {main()}")
