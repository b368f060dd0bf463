"""Body points, forces and torques of `simulate`, judged from independent computations: scipy's
rotations of the truncated ball's geometry, the fixed-frame integration, the steady circle's closed
forms (Eqs. 32-40) and finite differences of the integrated motion (M dv/dt = F, dL/dt = tau)."""
import math
import os

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import ballsurvey
from ballsurvey.simulate import simulate
from ballsurvey.synthetic import fixed_frame_states

PROBE = 0.03


@pytest.fixture(scope="module")
def square(ball):
    """Fig. 12a for 1.5 s, densely sampled (dt 5e-5 s, every step kept)."""
    return simulate(-5.0, 0.0, 4.05, -3.0, T=1.5, dt=5e-5, n_out=30001, ball=ball,
                    probe_m=PROBE)


def test_body_points_against_rotated_geometry_and_the_fixed_frame_integration(ball, square):
    ds = square.isel(time=slice(None, None, 300))
    th, ch = ds.theta.values, ds.chi.values
    # body frame at theta = chi = 0: xi = x, eta = y (the symmetry axis, C -> G), zeta = z; the
    # ball tilts by -theta about xi, then turns by chi about z (Euler angles, Eq. 3)
    rot = Rotation.from_euler("ZX", np.column_stack([ch, -th]))
    a, c, h = ball.a, ball.c, ball.cut_height
    g = np.column_stack([ds.x.values, ds.y.values, np.zeros(th.size)])
    centre = g - rot.apply([0.0, c, 0.0])
    centre[:, 2] = a  # the sphere's centre stands a above the table
    want = {"face": centre + rot.apply([0.0, -(a - h), 0.0]),
            "tip": centre + rot.apply([0.0, -(a - h) - PROBE, 0.0]),
            "contact": centre - [0.0, 0.0, a]}
    for name, w in want.items():
        assert np.allclose(ds[f"x_{name}"], w[:, 0], atol=1e-12, rtol=0), name
        assert np.allclose(ds[f"y_{name}"], w[:, 1], atol=1e-12, rtol=0), name
        if name != "contact":
            assert np.allclose(ds[f"z_{name}"], w[:, 2], atol=1e-12, rtol=0), name
    # G's height from the rotation: a + c eta_z
    assert np.allclose(ds.z_face + (a - h + c) * rot.apply([0, 1, 0])[:, 2],
                       a + c * rot.apply([0, 1, 0])[:, 2], atol=1e-12)
    # the same points from another integration with no Euler angles (axis e as a vector)
    v = fixed_frame_states(-5.0, 0.0, 4.05, -3.0, 0.0, 0.0, 0.0, ds.time.values, ball)
    e = v[:, 2:5] / np.linalg.norm(v[:, 2:5], axis=1, keepdims=True)
    tip = v[:, 0:2] * a - (c + a - h + PROBE) * e[:, :2]
    assert np.allclose(ds.x_tip, tip[:, 0], atol=2e-6) and np.allclose(ds.y_tip, tip[:, 1],
                                                                       atol=2e-6)


def test_fig4a_circles_of_centre_face_and_probe_tip(ball, fig4):
    kw, R = fig4
    ds = simulate(**kw, T=2 * math.pi / 3.23, n_out=801, ball=ball, probe_m=PROBE)
    th = math.radians(24.0)
    d_face = ball.c + ball.a - ball.cut_height
    # the circle's centre is the origin (Fig. 4 starts at y = -R); the axis's horizontal part is
    # radial, pointing in, so the face and the tip run outside G (Fig. 4a)
    for (xv, yv), radius in ((("x", "y"), R), (("x_face", "y_face"), R + d_face * math.cos(th)),
                             (("x_tip", "y_tip"), R + (d_face + PROBE) * math.cos(th))):
        r = np.hypot(ds[xv].values, ds[yv].values)
        assert np.allclose(r, radius, rtol=1e-6), (xv, r.mean(), radius)


def test_forces_and_torque_of_the_steady_circle_match_eqs_36_to_40(ball, fig4):
    kw, R = fig4
    ds = simulate(**kw, T=2.0, n_out=401, ball=ball)
    M, g, a, c = ball.M, ball.g, ball.a, ball.c
    th, Om = math.radians(24.0), -3.23
    om = kw["phidot0"]
    f_h = np.hypot(ds.Fx, ds.Fy)
    assert np.allclose(f_h, M * R * Om**2, rtol=1e-6)  # centripetal, M R Omega^2
    # friction points from G to the circle's centre (the origin)
    assert np.allclose((ds.Fx * ds.x + ds.Fy * ds.y) / (f_h * np.hypot(ds.x, ds.y)), -1,
                       atol=1e-6)
    assert np.allclose(ds.normal_force, M * g, rtol=1e-9) and np.allclose(ds.Fz, 0, atol=1e-9)
    # Eq. (40) with m = M, written out here
    tau_c = M * math.cos(th) * (-g * c + (a - c * math.sin(th)) * (a * om - c * Om) * Om)
    assert np.allclose(np.hypot(ds.tau_x, ds.tau_y), abs(tau_c), rtol=1e-6)
    assert np.allclose(ds.tau_z, 0, atol=1e-12)
    vx, vy = np.gradient(ds.x.values, ds.time.values), np.gradient(ds.y.values, ds.time.values)
    cross = (ds.tau_x * vy - ds.tau_y * vx) / (np.hypot(vx, vy) * abs(tau_c))
    assert np.max(np.abs(cross[5:-5])) < 1e-3  # parallel to the velocity (Eq. 39)


def test_force_and_torque_equal_the_rates_of_momentum_and_angular_momentum(ball, square):
    ds = square
    t = ds.time.values
    M, a, c, A, B = ball.M, ball.a, ball.c, ball.A, ball.B
    th, ch = ds.theta.values, ds.chi.values
    thd, chd, phd = ds.thetadot.values, ds.chidot.values, ds.phidot.values

    def d(v):
        return np.gradient(v, t, edge_order=2)

    sl = slice(10, -10)
    f = {"Fx": M * d(d(ds.x.values)), "Fy": M * d(d(ds.y.values)),
         "Fz": M * d(d(a - c * np.sin(th)))}
    for k, want in f.items():
        scale = np.max(np.abs(ds[k].values))
        assert np.max(np.abs(ds[k].values[sl] - want[sl])) < 2e-4 * scale, k
    # L_G = A w + (B - A) (w . eta) eta with w from Eq. (1), built in the fixed frame
    xi = np.column_stack([np.cos(ch), np.sin(ch), 0 * ch])
    eta = np.column_stack([-np.cos(th) * np.sin(ch), np.cos(th) * np.cos(ch), -np.sin(th)])
    zeta = np.cross(xi, eta)
    w = (-thd[:, None] * xi + (phd - chd * np.sin(th))[:, None] * eta
         + (chd * np.cos(th))[:, None] * zeta)
    L = A * w + (B - A) * np.sum(w * eta, axis=1)[:, None] * eta
    for j, k in enumerate(("tau_x", "tau_y", "tau_z")):
        scale = np.max(np.abs(ds[k].values))
        assert np.max(np.abs(ds[k].values[sl] - d(L[:, j])[sl])) < 2e-4 * scale, k


def _pose(theta_deg, chi_deg=0.0, phi=0.0):
    import xarray as xr

    one = ("time", [0.0])
    return xr.Dataset({"x": one, "y": one, "theta": ("time", [math.radians(theta_deg)]),
                       "chi": ("time", [math.radians(chi_deg)]), "phi": ("time", [phi])})


def test_animation_geometry_is_the_truncated_ball(ball):
    from ballsurvey.animate import ball_geometry, silhouette

    a, h = ball.a, ball.cut_height
    geo = ball_geometry(_pose(30.0, 40.0, 1.0), 0, ball, PROBE)
    rim = geo["rim"] - geo["C"]
    assert np.allclose(np.linalg.norm(rim, axis=1), a)  # the rim lies on the sphere
    assert np.allclose(rim @ -geo["eta"], a - h)  # in the cut's plane
    assert np.isclose(np.linalg.norm(geo["spot"] - geo["C"]), a)
    assert np.isclose(geo["contact"][2], 0.0) and np.isclose(geo["C"][2], a)
    # axis horizontal, seen from above: a disc less the circular segment cut off
    geo = ball_geometry(_pose(0.0), 0, ball, PROBE)
    p = silhouette(geo, np.array([0.0, 0.0, 1.0]), (0, 1), ball)
    area = 0.5 * abs(np.dot(p[:, 0], np.roll(p[:, 1], 1)) - np.dot(p[:, 1], np.roll(p[:, 0], 1)))
    d = a - h
    want = math.pi * a * a - (a * a * math.acos(d / a) - d * math.sqrt(a * a - d * d))
    assert abs(area / want - 1) < 2e-3
    # seen along the axis, face towards us: the whole disc
    geo = ball_geometry(_pose(0.0), 0, ball, PROBE)
    p = silhouette(geo, np.array([0.0, -1.0, 0.0]), (0, 2), ball)
    area = 0.5 * abs(np.dot(p[:, 0], np.roll(p[:, 1], 1)) - np.dot(p[:, 1], np.roll(p[:, 0], 1)))
    assert abs(area / (math.pi * a * a) - 1) < 2e-3


def test_animate_writes_a_gif_of_the_frames_asked_and_refuses_mp4_without_ffmpeg(
        tmp_path, capsys, monkeypatch):
    from PIL import Image

    from ballsurvey import animate
    from ballsurvey.cli import main

    out = tmp_path / "ball.gif"
    assert main(["animate", "--theta0-deg", "-5", "--chidot0", "4.05", "--phidot0", "-3",
                 "--T", "0.3", "--fps", "10", "--speed", "1", "-o", str(out)]) == 0
    assert "(4 frames, 10 fps, 1x speed)" in capsys.readouterr().out
    with Image.open(out) as im:
        assert im.format == "GIF" and im.n_frames == 4
    monkeypatch.setattr(animate.shutil, "which", lambda name: None)
    assert main(["animate", "--theta0-deg", "-5", "--chidot0", "4.05", "--phidot0", "-3",
                 "-o", str(tmp_path / "ball.mp4")]) == 2
    err = capsys.readouterr().err
    assert "ffmpeg" in err and err.count("\n") == 1
    assert not (tmp_path / "ball.mp4").exists()


def test_path_show_and_forces_write_both_figures_and_refuse_unknown_points(tmp_path, capsys):
    from ballsurvey.cli import main

    out = tmp_path / "p.png"
    args = ["path", "--theta0-deg", "24", "--chidot0", "-3.23", "--phidot0", "-10.21",
            "--T", "0.5", "--n-out", "201", "-o", str(out)]
    assert main(args + ["--show", "probe,face", "--forces"]) == 0
    assert out.stat().st_size > 0 and (tmp_path / "p-forces.png").stat().st_size > 0
    assert main(args + ["--show", "probe,nose"]) == 2
    assert "nose" in capsys.readouterr().err


OTHER_BALL = "a=0.03,c=0.005,M=0.12,A=3.2e-5,B=3.6e-5,cut_height=0.01"


def test_ball_options_reach_the_integration_and_bad_balls_are_one_line(tmp_path, capsys):
    from ballsurvey.ball import Ball
    from ballsurvey.cli import main
    from ballsurvey.sweep.spec import load_spec

    launch = ["--theta0-deg", "-5", "--chidot0", "4.05", "--phidot0", "-3", "--T", "4",
              "--n-out", "401"]
    other = Ball(a=0.03, c=0.005, M=0.12, A=3.2e-5, B=3.6e-5, cut_height=0.01)
    want = simulate(-5.0, 0.0, 4.05, -3.0, T=4.0, n_out=401, ball=other).attrs["n_sides"]
    paper = simulate(-5.0, 0.0, 4.05, -3.0, T=4.0, n_out=401).attrs["n_sides"]
    assert abs(want - paper) > 0.01
    assert main(["path", *launch, "--ball", OTHER_BALL, "-o", str(tmp_path / "p.png")]) == 0
    assert f"n = {want:.3f}" in capsys.readouterr().out
    # a spec's [ball], read by the spec's own rules
    spec = tmp_path / "s.toml"
    spec.write_text(f"[ball]\n{OTHER_BALL.replace(',', chr(10))}\n[launch]\ntheta0_deg = 0.0\n"
                    "thetadot0 = 0.0\nchidot0 = 1.0\nphidot0 = -3.0\n[run]\nT = 1.0\n")
    assert load_spec(spec).ball == other
    assert main(["path", *launch, "--spec", str(spec), "-o", str(tmp_path / "q.png")]) == 0
    assert f"n = {want:.3f}" in capsys.readouterr().out
    for bad, words in ((["--ball", "a=0.03,c=x"], "'x' is not a number"),
                       (["--ball", "a=0.03,c=0.005,M=0.1,A=1e-5,B=3e-5"], "B <= 2A"),
                       (["--ball", "a=0.03,q=1"], "unknown key"),
                       (["--cut-height", "-1"], "--cut-height"),
                       (["--spec", str(spec), "--ball", OTHER_BALL], "not both")):
        assert main(["path", *launch, *bad, "-o", str(tmp_path / "r.png")]) == 2
        err = capsys.readouterr().err
        assert words in err and err.count("\n") == 1, err
    assert not (tmp_path / "r.png").exists()


def test_plot_path_returns_a_figure_without_a_file(square):
    from matplotlib.figure import Figure

    from ballsurvey.plot import plot_path

    fig = plot_path(square.isel(time=slice(None, None, 30)), show=("probe", "face"))
    assert isinstance(fig, Figure)
    texts = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert "tip of the probe" in texts and "centre of the flat face" in texts


def test_find_with_another_ball_solves_for_that_ball(capsys):
    import re

    from ballsurvey.ball import Ball
    from ballsurvey.cli import main

    assert main(["find", "--shape", "square", "--theta0-deg", "-5", "--phidot0", "-3",
                 "--ball", OTHER_BALL]) == 0
    roots = [float(v) for v in re.findall(r"^chidot0 = (\S+) rad/s", capsys.readouterr().out,
                                          re.M)]  # the solutions, not the roots refused
    assert roots and all(abs(r - 4.0526) > 0.1 for r in roots)  # not the paper ball's square
    other = Ball(a=0.03, c=0.005, M=0.12, A=3.2e-5, B=3.6e-5, cut_height=0.01)
    for r in roots:  # each closes a square with that ball, judged by integration here
        a = simulate(-5.0, 0.0, r, -3.0, T=20.0, ball=other, method="dopri5", rtol=1e-10).attrs
        assert a["label"] == "square" and abs(a["n_sides"] - 4) < 1e-3


def test_animate_frames_are_the_pictures_matplotlib_saves_and_explain_the_spot(tmp_path):
    """write_animation's frames (background drawn once, moving parts drawn onto it) against the
    same animation saved by matplotlib's PillowWriter (every frame drawn whole by savefig)."""
    from matplotlib.animation import PillowWriter

    from ballsurvey import animate

    ds = ballsurvey.simulate(-5.0, 0.0, 4.05, -3.0, T=0.3, n_out=301)
    writer = PillowWriter(fps=10)
    anim = animate.animation(ds, fps=10, speed=0.3)
    labels = [t.get_text() for leg in anim._fig.legends for t in leg.get_texts()]
    assert any("spot" in s and "spin" in s for s in labels), labels
    assert any("centre of mass" in s for s in labels), labels
    anim.save(tmp_path / "a.gif", writer=writer, dpi=animate.DPI)
    whole = [np.asarray(im, dtype=int) for im in writer._frames]
    fast = [np.asarray(f, dtype=int)[..., :3].copy()
            for f in animate.frames(ds, fps=10, speed=0.3)]
    assert len(whole) == len(fast) == 11
    for k in (0, 5, 10):
        differ = np.any(whole[k] != fast[k], axis=-1)
        assert differ.mean() < 1e-4, (k, differ.mean())
    # the frames move: the ball is drawn where it is, not once
    assert np.any(fast[0] != fast[10])
    # and no two tick labels run into each other
    renderer = anim._fig.canvas.get_renderer()
    for axis in [a for ax in anim._fig.axes for a in (ax.xaxis, ax.yaxis)]:
        boxes = [t.get_window_extent(renderer) for t in axis.get_ticklabels() if t.get_text()]
        assert not any(b1.overlaps(b2) for i, b1 in enumerate(boxes) for b2 in boxes[i + 1:])


def test_animate_pipes_its_frames_to_ffmpeg_for_an_mp4(tmp_path, monkeypatch):
    """An .mp4 is the raw RGBA frames piped to ffmpeg (a stand-in here that keeps the bytes)."""
    import matplotlib

    from ballsurvey import animate

    fake = tmp_path / "bin" / "ffmpeg"
    fake.parent.mkdir()
    fake.write_text(f"#!/bin/sh\nfor last; do :; done\ncat > \"$last\"\necho \"$@\" > "
                    f"{tmp_path}/args\n")
    fake.chmod(0o755)
    monkeypatch.setenv("PATH", f"{fake.parent}:{os.environ['PATH']}")
    monkeypatch.setitem(matplotlib.rcParams, "animation.ffmpeg_path", str(fake))
    ds = ballsurvey.simulate(-5.0, 0.0, 4.05, -3.0, T=0.3, n_out=61)
    out = animate.write_animation(ds, tmp_path / "ball.mp4", fps=10, speed=1)
    h, w = 416, 800
    assert out.stat().st_size == 4 * h * w * 4  # 4 frames of 800 x 416 RGBA
    args = (tmp_path / "args").read_text().split()
    assert args[args.index("-s") + 1] == f"{w}x{h}" and args[args.index("-pix_fmt") + 1] == "rgba"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["args", "ball.mp4", "bin"]
