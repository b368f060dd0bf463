"""The ball, animated: a top view with the path being traced and a side view that follows the ball,
the truncated ball drawn with its flat face, its probe and a spot on its equator (so the spin
shows), from a `simulate` trajectory.

GIF through Pillow (a matplotlib dependency), MP4 through ffmpeg where it is installed.
"""
from __future__ import annotations

import math
import os
import shutil
from pathlib import Path

import numpy as np
import xarray as xr

from .ball import Ball
from .limits import InputError, RunError

#: frames per second of the file, and motion seconds per playback second (0.5: half speed)
FPS = 20
SPEED = 0.5
#: most frames one animation may have
MAX_FRAMES = 5000
#: rim points drawn for the flat face and the outline
N_RIM = 48
#: dots per inch of the written frames (800 x 416 pixels)
DPI = 80


def check_output(out) -> Path:
    """The output file: .gif, or .mp4 with ffmpeg on the PATH; InputError (one line) if not."""
    p = Path(out)
    suffix = p.suffix.lower()
    if suffix not in (".gif", ".mp4"):
        raise InputError(f"{out} must end in .gif or .mp4")
    if p.is_dir():
        raise InputError(f"{out} is a folder")
    if suffix == ".mp4" and shutil.which("ffmpeg") is None:
        raise InputError("an .mp4 needs ffmpeg on the PATH, which is not there; install "
                         "ffmpeg or write a .gif")
    return p


def frame_count(T: float, fps: float = FPS, speed: float = SPEED) -> int:
    """Frames of an animation of T seconds of motion; InputError beyond MAX_FRAMES."""
    n = int(math.floor(T / speed * fps + 1e-6)) + 1  # + 1e-6: T read back from samples
    if n > MAX_FRAMES:
        raise InputError(f"{n} frames is more than {MAX_FRAMES}; shorten T, lower fps or raise "
                         "speed")
    return n


def frame_indices(ds: xr.Dataset, fps: float = FPS, speed: float = SPEED) -> np.ndarray:
    """Samples of `ds` shown, one per frame: fps frames a playback second, speed motion seconds
    a playback second."""
    t = ds.time.values
    n = frame_count(t[-1] - t[0], fps, speed)
    want = t[0] + np.arange(n) * speed / fps
    return np.clip(np.searchsorted(t, want), 0, t.size - 1)


def ball_geometry(ds: xr.Dataset, k: int, ball: Ball, probe_m: float) -> dict:
    """3-D points (m) of the ball at sample k: centre C, G, the flat face's rim (N_RIM, 3) and
    centre, the probe's tip, the contact point, a spot on the equator (body-fixed: phi turns it
    about the axis), and the axis eta (Eq. 3)."""
    th, ch, ph = (float(ds[v].values[k]) for v in ("theta", "chi", "phi"))
    sth, cth, sch, cch = math.sin(th), math.cos(th), math.sin(ch), math.cos(ch)
    xi = np.array([cch, sch, 0.0])
    eta = np.array([-cth * sch, cth * cch, -sth])
    zeta = np.cross(xi, eta)
    a, c, h = ball.a, ball.c, ball.cut_height
    g = np.array([float(ds.x.values[k]), float(ds.y.values[k]), a - c * sth])
    centre = g - c * eta
    face = centre - (a - h) * eta
    r_face = math.sqrt(max(a * a - (a - h) ** 2, 0.0))
    al = np.linspace(0, 2 * np.pi, N_RIM)
    rim = face + r_face * (np.outer(np.cos(al), xi) + np.outer(np.sin(al), zeta))
    spot = centre + a * (math.cos(ph) * xi - math.sin(ph) * zeta)
    return {"C": centre, "G": g, "face": face, "rim": rim, "tip": face - probe_m * eta,
            "contact": centre - np.array([0.0, 0.0, a]), "spot": spot, "eta": eta}


def silhouette(geo: dict, view: np.ndarray, dims, ball: Ball, off=None) -> np.ndarray:
    """The truncated ball's outline seen along `view` (a unit vector), in the plane of the
    coordinates `dims`: the convex hull of the sphere's outline where the cap is not cut off and
    of the flat face's rim (the truncated ball is convex)."""
    from scipy.spatial import ConvexHull

    a, h = ball.a, ball.cut_height
    u = np.cross(view, [1.0, 0.0, 0.0] if abs(view[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(view, u)
    al = np.linspace(0, 2 * np.pi, 4 * N_RIM, endpoint=False)
    ring = a * (np.outer(np.cos(al), u) + np.outer(np.sin(al), v))
    kept = ring[ring @ -geo["eta"] <= a - h] + geo["C"]
    pts = np.vstack([kept, geo["rim"]]) - (np.zeros(3) if off is None else off)
    pts = pts[:, list(dims)]
    return pts[ConvexHull(pts).vertices]


def _scene(ds: xr.Dataset, ball: Ball, fps: float, speed: float, probe_m: float | None,
           dpi: float = DPI):
    """The animation's figure, its frames' sample indices, a `draw(f)` that sets every moving
    artist to frame f, and the moving artists of each axes (drawn again on every frame)."""
    from matplotlib.figure import Figure
    from matplotlib.patches import Polygon
    from matplotlib.ticker import MaxNLocator

    probe_m = float(ds.attrs.get("probe_m", 0.0254)) if probe_m is None else probe_m
    idx = frame_indices(ds, fps, speed)
    a = ball.a
    x, y = ds.x.values, ds.y.values
    fig = Figure(figsize=(10, 5.2), dpi=dpi, layout="constrained")
    top, side = fig.subplots(1, 2, width_ratios=[1.3, 1])
    pad = a + probe_m
    top.set_xlim(x.min() - pad, x.max() + pad)
    top.set_ylim(y.min() - pad, y.max() + pad)
    top.set_aspect("equal")
    top.set_xlabel("x (m)")
    top.set_ylabel("y (m)")
    top.set_title("from above", fontsize=10)
    side.set_aspect("equal")
    side.set_xlabel("x - x_G (m)")
    side.set_ylabel("z (m)")
    side.set_title("from the side (looking along +y)", fontsize=10)
    side.set_xlim(-2.2 * a, 2.2 * a)
    side.set_ylim(-0.1 * a, 2 * a + probe_m + 0.2 * a)
    for axv in (top, side):  # few enough ticks that labels such as -0.075 never collide
        axv.xaxis.set_major_locator(MaxNLocator(nbins=5))
        axv.yaxis.set_major_locator(MaxNLocator(nbins=6))
    table = side.axhline(0.0, color="0.3", lw=1.5)
    path_line, = top.plot([], [], color="tab:red", lw=1.2, label="centre of mass")
    tip_line, = top.plot([], [], color="0.2", lw=0.6, label="probe tip")
    art = {}
    for name, axv, (i, j) in (("top", top, (0, 1)), ("side", side, (0, 2))):
        art[name] = dict(
            outline=axv.add_patch(Polygon(np.zeros((3, 2)), closed=True, fc="#f3e6c8", ec="0.3",
                                          lw=1)),
            face=axv.add_patch(Polygon(np.zeros((N_RIM, 2)), closed=True, fc="#c8a060",
                                       ec="0.2", lw=0.8)),
            probe=axv.plot([], [], color="k", lw=2)[0],
            spot=axv.plot([], [], "o", color="tab:blue", ms=5)[0],
            g=axv.plot([], [], "+", color="tab:red", ms=8)[0], dims=(i, j))
    # below the axes, clear of the path: what each mark is (the spot shows the spin about the
    # ball's axis; faint where it is on the far side)
    fig.legend(handles=[path_line, tip_line, art["top"]["g"], art["top"]["spot"]],
               labels=["path of the centre of mass", "path of the probe's tip",
                       "centre of mass G", "spot on the equator: turns with the spin"],
               loc="outside lower center", ncols=4, fontsize=8, frameon=False)
    time_text = top.text(0.02, 0.97, "", transform=top.transAxes, va="top", fontsize=9)
    views = {"top": np.array([0.0, 0.0, 1.0]), "side": np.array([0.0, -1.0, 0.0])}

    def draw(f):
        k = idx[f]
        geo = ball_geometry(ds, k, ball, probe_m)
        path_line.set_data(x[:k + 1], y[:k + 1])
        if "x_tip" in ds:
            tip_line.set_data(ds.x_tip.values[:k + 1], ds.y_tip.values[:k + 1])
        shift = np.array([geo["G"][0], 0.0, 0.0])
        for name, parts in art.items():
            i, j = parts["dims"]
            off = shift if name == "side" else np.zeros(3)

            def pt(p, i=i, j=j, off=off):
                q = np.asarray(p) - off
                return q[..., i], q[..., j]

            parts["outline"].set_xy(silhouette(geo, views[name], (i, j), ball, off))
            rx, ry = pt(geo["rim"])
            parts["face"].set_xy(np.column_stack([rx, ry]))
            facing = float(np.dot(-geo["eta"], views[name])) > 0  # the face turned to us
            parts["face"].set_alpha(1.0 if facing else 0.25)
            parts["face"].set_zorder(3 if facing else 1.5)
            bx, by = pt(geo["face"])
            tx, ty = pt(geo["tip"])
            parts["probe"].set_data([bx, tx], [by, ty])
            parts["probe"].set_zorder(4 if facing else 1.4)
            sx, sy = pt(geo["spot"])
            parts["spot"].set_data([sx], [sy])
            seen = float(np.dot(geo["spot"] - geo["C"], views[name])) > 0
            parts["spot"].set_alpha(1.0 if seen else 0.2)
            gx, gy = pt(geo["G"])
            parts["g"].set_data([gx], [gy])
        time_text.set_text(f"t = {ds.time.values[k]:.2f} s, theta = "
                           f"{math.degrees(ds.theta.values[k]):.1f} deg")
        return []

    lab = ds.attrs.get("label", "")
    fig.suptitle(f"{lab}: theta0 = {ds.attrs.get('theta0_deg')} deg, chidot0 = "
                 f"{ds.attrs.get('chidot0')}, phidot0 = {ds.attrs.get('phidot0')} rad/s "
                 f"({speed:g}x speed)", fontsize=10)
    moving = {top: [path_line, tip_line, time_text], side: [table]}
    for name, axv in (("top", top), ("side", side)):
        moving[axv] += [v for k, v in art[name].items() if k != "dims"]
    for artists in moving.values():  # the layout is the still parts'
        for artist in artists:
            artist.set_in_layout(False)
    _settle(fig)
    return fig, idx, draw, moving


def _settle(fig) -> None:
    """Lay `fig` out once for all its frames: constrained layout with equal-aspect axes moves the
    axes a little at each drawing until it settles (a few drawings); drawn until it has, then
    frozen, so the axes stand still from the first frame to the last."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(fig)
    before = None
    for _ in range(12):
        canvas.draw()
        now = np.array([ax.get_position().bounds for ax in fig.axes])
        if before is not None and np.abs(now - before).max() < 1e-5:
            break
        before = now
    fig.set_layout_engine("none")


def animation(ds: xr.Dataset, ball: Ball | None = None, fps: float = FPS, speed: float = SPEED,
              probe_m: float | None = None):
    """A matplotlib FuncAnimation of a `simulate` Dataset: top view (x, y) with the path traced
    and the ball at true scale, side view (x, z) following the ball. In a notebook:
    ``IPython.display.HTML(animation(ds).to_jshtml())``. (`write_animation` draws the same
    frames faster: it draws the still parts once.)"""
    from matplotlib.animation import FuncAnimation

    fig, idx, draw, _ = _scene(ds, ball or Ball.paper(), fps, speed, probe_m)
    return FuncAnimation(fig, draw, frames=len(idx), interval=1000.0 / fps, blit=False)


def frames(ds: xr.Dataset, ball: Ball | None = None, fps: float = FPS, speed: float = SPEED,
           probe_m: float | None = None, dpi: float = DPI):
    """The animation's frames as RGBA arrays (height, width, 4), the same pictures as
    `animation` saved at `dpi`, drawn faster: the figure is drawn once without its moving parts,
    and each frame puts that background back and draws only the moving parts (the ball, the
    paths and the clock), each axes' in their stacking order. The array is the canvas's buffer,
    overwritten by the next frame."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig, idx, draw, moving = _scene(ds, ball or Ball.paper(), fps, speed, probe_m, dpi)
    canvas = FigureCanvasAgg(fig)
    for artists in moving.values():
        for artist in artists:
            artist.set_animated(True)
    canvas.draw()
    background = canvas.copy_from_bbox(fig.bbox)
    for f in range(len(idx)):
        draw(f)
        canvas.restore_region(background)
        for axv, artists in moving.items():
            for artist in sorted(artists, key=lambda art: art.get_zorder()):
                axv.draw_artist(artist)
        yield np.asarray(canvas.buffer_rgba())


def write_animation(ds: xr.Dataset, out, ball: Ball | None = None, fps: float = FPS,
                    speed: float = SPEED, probe_m: float | None = None) -> Path:
    """Write the animation's `frames` to out (.gif with Pillow, .mp4 with ffmpeg, as
    matplotlib's PillowWriter and FFMpegWriter write them); returns the path."""
    import subprocess

    from matplotlib import rcParams
    from PIL import Image

    p = check_output(out)
    p.parent.mkdir(parents=True, exist_ok=True)
    # written beside the target and renamed when whole: a Ctrl-C or a full disk leaves no
    # truncated file that looks like an animation
    tmp = p.with_name(f".{p.stem}.partial{p.suffix}")
    try:
        pictures = frames(ds, ball, fps, speed, probe_m)
        if p.suffix.lower() == ".gif":
            shots = [Image.fromarray(rgba, "RGBA").convert("RGB") for rgba in pictures]
            shots[0].save(tmp, format="GIF", save_all=True, append_images=shots[1:],
                          duration=int(1000 / fps), loop=0)
        else:
            first = next(pictures)
            h, w = first.shape[:2]
            cmd = [rcParams["animation.ffmpeg_path"], "-f", "rawvideo", "-vcodec", "rawvideo",
                   "-s", f"{w}x{h}", "-pix_fmt", "rgba", "-framerate", str(fps), "-loglevel",
                   "error", "-i", "pipe:", "-vcodec", "h264", "-pix_fmt", "yuv420p", "-y",
                   "-f", "mp4", str(tmp)]
            with subprocess.Popen(cmd, stdin=subprocess.PIPE, stderr=subprocess.PIPE) as proc:
                try:
                    proc.stdin.write(first.tobytes())
                    for rgba in pictures:
                        proc.stdin.write(rgba.tobytes())
                finally:
                    proc.stdin.close()
                    err = proc.stderr.read().decode(errors="replace").strip()
                    if proc.wait() != 0:
                        raise RunError(f"ffmpeg failed writing {p}: "
                                       f"{err.splitlines()[-1] if err else proc.returncode}")
        os.replace(tmp, p)
    finally:
        tmp.unlink(missing_ok=True)
    return p
