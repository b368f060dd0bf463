"""Draws docs/img/conventions.png: which way the ball starts for each sign of phidot0 and
chidot0, and what chi0 is on a video frame (the table seen from above, as a camera sees it).

Each panel: one launch at chi0 = 30 deg (theta0 = -5 deg, thetadot0 = 0), integrated by
`ballsurvey.simulate`; the ball's outline at the start, the direction xi = (cos chi0, sin chi0)
from which chi0 is measured, the flat face and probe (they point to chi0 - 90 deg), G's
initial velocity (arrow) and the first 0.4 s of its path.

    python examples/draw_conventions.py             # writes docs/img/conventions.png
"""
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Circle

import ballsurvey
from ballsurvey.ball import Ball
from ballsurvey.fit import heading_deg

OUT = Path(__file__).resolve().parents[1] / "docs" / "img" / "conventions.png"
THETA0, CHI0, T = -5.0, 30.0, 0.4


def main(out: Path = OUT) -> Path:
    ball = Ball.paper()
    fig = Figure(figsize=(8.4, 8.8), layout="constrained")
    axs = fig.subplots(2, 2)
    for row, phd in enumerate((-3.0, 3.0)):
        for col, chd in enumerate((-4.05, 4.05)):
            ax = axs[row, col]
            ds = ballsurvey.simulate(THETA0, 0.0, chd, phd, T=T, chi0_deg=CHI0, n_out=601,
                                     ball=ball)
            x, y = ds.x.values * 100, ds.y.values * 100
            ax.plot(x, y, "-", color="C3", lw=1.5, label=f"path of G (first {T:g} s)")
            ax.add_patch(Circle((0, 0), ball.a * 100, fill=False, color="0.4", lw=1))
            r = ball.a * 100
            c, s = np.cos(np.radians(CHI0)), np.sin(np.radians(CHI0))
            ax.annotate("", xy=(1.6 * r * c, 1.6 * r * s), xytext=(0, 0),
                        arrowprops=dict(arrowstyle="->", color="0.3", ls="--"))
            ax.text(1.7 * r * c - 1.0, 1.7 * r * s + 0.3, "xi: chi0 = 30 deg", fontsize=8,
                    color="0.3")
            fx, fy = ds.x_face.values[0] * 100, ds.y_face.values[0] * 100
            tx, ty = ds.x_tip.values[0] * 100, ds.y_tip.values[0] * 100
            ax.plot([fx, tx], [fy, ty], "-", color="C0", lw=3, label="flat face and probe")
            ax.plot([fx], [fy], "s", color="C0", ms=5)
            hd = heading_deg([THETA0, 0.0, chd, phd, CHI0, 0.0, 0.0], ball)
            h = np.radians(hd)
            ax.annotate("", xy=(2.2 * r * np.cos(h), 2.2 * r * np.sin(h)), xytext=(0, 0),
                        arrowprops=dict(arrowstyle="-|>", color="k", lw=1.5))
            # the label beside the arrow's tip, clear of xi's label when they point alike
            lx, ly = (2.3 * r * np.cos(h) - 1.5, 2.3 * r * np.sin(h) - 0.9) if phd < 0 \
                else (1.0, 5.6)
            ax.text(lx, ly, f"G starts at {hd:.0f} deg", fontsize=8)
            ax.set_title(f"phidot0 {phd:+g}, chidot0 {chd:+g} rad/s: chi turns "
                         f"{'ccw' if chd > 0 else 'cw'}", fontsize=9)
            ax.set_xlim(-7, 7)
            ax.set_ylim(-7, 7)
            ax.set_aspect("equal")
            ax.axhline(0, color="0.85", lw=0.5)
            ax.axvline(0, color="0.85", lw=0.5)
            ax.set_xlabel("x (cm)")
            ax.set_ylabel("y (cm)")
            if row == 0 and col == 0:
                ax.legend(fontsize=7, loc="lower left")
    fig.suptitle("Seen from above (a video frame, y up): chi0 is the direction of xi; the flat "
                 "face points to chi0 - 90 deg;\nG starts along chi0 + 180 deg when a phidot0 < "
                 "c chidot0 (phidot0 < 0 here), along chi0 otherwise (thetadot0 = 0)",
                 fontsize=9)
    fig.savefig(out, dpi=85)
    return out


if __name__ == "__main__":
    print(f"wrote {main()}")
