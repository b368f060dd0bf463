"""The fit drawn over its track (`plot_fit`)."""
from __future__ import annotations

import numpy as np

from ..ball import Ball
from .model import PARAMS, fitted_track
from .track import Track

#: the plot's model drawn every PLOT_DT seconds (or finer)
PLOT_DT = 0.01


def plot_fit(track: Track, fit: dict, out=None, ball: Ball | None = None):
    """Track and fitted launch overlaid: the path in the plane (m), and theta (deg) and chidot
    (rad/s) against time where the track has them. The model is drawn dense in time (every
    10 ms or finer) over the whole track, the dropped frames' model positions marked with
    crosses, and the alternative launches that fit as well drawn dashed. Returns the
    matplotlib Figure; writes it to `out` (PNG) if given."""
    from matplotlib.figure import Figure  # the object API: no global matplotlib state

    T = float(track.t[-1])
    dense = np.linspace(0.0, T, max(int(T / PLOT_DT) + 1, 2 * track.t.size))
    model = fitted_track(fit, track, ball, times=dense)
    lost = track.dropped_t - track.t_start
    lost = lost[(lost >= 0) & (lost <= T)]
    at_lost = fitted_track(fit, track, ball, times=lost) if lost.size else None
    alts = [fitted_track(a, track, ball, times=dense) for a in fit.get("alternatives", [])]
    extra = [k for k in ("theta_deg", "chidot") if getattr(track, k) is not None]
    fig = Figure(figsize=(6 + 4 * len(extra), 5.5), layout="constrained")
    axs = fig.subplots(1, 1 + len(extra), squeeze=False)
    ax = axs[0, 0]
    pairs = [("x_tip", "y_tip", "probe tip"), ("x_base", "y_base", "probe base")] \
        if track.probe else [("x", "y", "centre of mass")]
    for (px, py, what), col in zip(pairs, ("C0", "C2")):
        ax.plot(getattr(track, px), getattr(track, py), ".", ms=2, color=col,
                label=f"track: {what}")
        ax.plot(model[px], model[py], "-", lw=1, color="k" if col == "C0" else "C3",
                label=f"fit: {what}")
        for i, alt in enumerate(alts):
            ax.plot(alt[px], alt[py], "--", lw=0.8, color=f"C{4 + i}",
                    label=f"also fits: {what}" if i == 0 else None)
        if at_lost is not None:
            ax.plot(at_lost[px], at_lost[py], "x", ms=5, color="C1",
                    label="dropped frames (model)" if col == "C0" else None)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(fontsize=8)
    ax.set_title(f"fit: {fit['label']}, {fit.get('status', 'ok')}, rms "
                 f"{fit['rms_m'] * 1e3:.3f} mm", fontsize=10)
    for axe, k in zip(axs[0, 1:], extra):
        axe.plot(track.t, getattr(track, k), ".", ms=2, label="track")
        axe.plot(dense, model[k], "k-", lw=1, label="fit")
        for i, alt in enumerate(alts):
            axe.plot(dense, alt[k], "--", lw=0.8, color=f"C{4 + i}",
                     label="also fits" if i == 0 else None)
        if at_lost is not None:
            axe.plot(lost, at_lost[k], "x", ms=5, color="C1", label="dropped frames (model)")
        axe.set_xlabel("t since the first sample (s)")
        axe.set_ylabel({"theta_deg": "theta (deg)", "chidot": "chidot (rad/s)"}[k])
        axe.legend(fontsize=8)
    # two short lines: one long one ran off a one-panel figure at both edges
    angles = ", ".join(f"{k} {fit[k]:.4g}" for k in PARAMS[:5] if k.endswith("_deg"))
    rates = ", ".join(f"{k} {fit[k]:.4g}" for k in PARAMS[:5] if not k.endswith("_deg"))
    fig.suptitle(f"{angles} (deg)\n{rates} (rad/s)", fontsize=9)
    if out is not None:
        fig.savefig(out, dpi=120)
    return fig
