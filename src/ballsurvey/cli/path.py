"""`ballsurvey path`: integrate one launch and draw it."""
from __future__ import annotations

import math

from .options import (
    UserError,
    _add_ball_options,
    _add_launch_options,
    _add_rolling_option,
    _ball_arg,
    _figure_file,
    _launch_opt,
    _opt,
    _out_file,
    _rolling_opt,
)

#: path's integration time (s) when --T is not given: long enough for the label on most launches
PATH_T = 20.0


def run(args):
    from .. import limits
    from ..plot import (
        BODY_POINTS,
        cycles_per_orbit,
        is_steady,
        orbit_window,
        plot_forces,
        plot_path,
        shape_text,
    )
    from ..simulate import check_simulate_inputs, simulate

    out = _figure_file(args.output)
    dpi = _opt("--dpi", args.dpi, integer=True, lo=20, hi=1200)
    ball = _ball_arg(args)
    for name in ("theta0_deg", "thetadot0", "chidot0", "phidot0", "chi0_deg"):
        _launch_opt("--" + name.replace("_", "-"), name, getattr(args, name), ball)
    T = args.T if args.T is not None else PATH_T
    show = [w.strip() for w in (args.show or "").split(",") if w.strip()]
    for w in show:
        if w not in BODY_POINTS:
            raise UserError(f"--show: unknown body point {w!r}; known: {', '.join(BODY_POINTS)}")
    probe = _opt("--probe-m", args.probe_m, nonnegative=True, hi=1.0)
    mu_r = _rolling_opt(args)
    forces_out = out.with_name(out.stem + "-forces" + out.suffix) if args.forces else None
    if forces_out is not None:
        _out_file("--forces", str(forces_out), out.suffix)  # a folder there, unwritable: refused
    try:
        limits.steps(T, args.dt, "--T", "--dt")
        limits.samples(args.n_out, "--n-out")
        check_simulate_inputs(args.theta0_deg, args.thetadot0, args.chidot0, args.phidot0, T,
                              args.dt, args.chi0_deg, n_out=args.n_out, ball=ball)
    except limits.InputError as exc:
        raise UserError(str(exc)) from None
    ds = simulate(args.theta0_deg, args.thetadot0, args.chidot0, args.phidot0, T, dt=args.dt,
                  chi0_deg=args.chi0_deg, n_out=args.n_out, ball=ball, probe_m=probe,
                  rolling_resistance=mu_r)
    drawn, shown = ds, ""
    if args.T is None:  # the label from PATH_T seconds, the figure of a few orbits
        window = orbit_window(ds.attrs, T)
        if window < T:
            drawn = ds.sel(time=slice(0.0, window))
            drawn.attrs = ds.attrs
            cycles = window / float(ds.attrs["theta_period_s"])
            orbits = cycles / cycles_per_orbit(ds.attrs)
            orbits = (f"{orbits:.3g} orbits" if orbits >= 1.005 else
                      "one orbit" if orbits > 0.995 else f"{orbits:.2g} of an orbit")
            shown = (f"; drew the first {window:.3g} s ({cycles:.3g} theta cycles, {orbits}; "
                     "at most 3 orbits or 36 cycles without --T)")
    out.parent.mkdir(parents=True, exist_ok=True)
    plot_path(drawn, out, ball=ball, panels=args.panels, dpi=dpi, show=show)
    if forces_out is not None:
        plot_forces(drawn, forces_out,
                    title=f"net force and torque about G: {ds.attrs['label']}")
        out = f"{out} and {forces_out}"
    a = ds.attrs
    if is_steady(a):
        from ..classify.labels import Thresholds

        turn = (f"steady (theta stays within {Thresholds().steady_theta_tol_deg:g} deg: no theta "
                "cycle, no turn per cycle)")
    elif math.isfinite(float(a["turn_per_cycle_deg"])):
        turn = f"turn per cycle {a['turn_per_cycle_deg']:.3f} deg"
    else:
        turn = f"no turn per cycle (too few theta cycles in {T:g} s)"
    print(f"{shape_text(a)}; {turn}, theta {a['theta_min_deg']:.2f}..{a['theta_max_deg']:.2f} "
          f"deg (label from {T:g} s){shown}; wrote {out}")


def add_parser(cmd):
    """`ballsurvey path`'s parser, made by `cmd` (`build_parser`'s)."""
    q = cmd("path", help="integrate one launch and draw it like the paper's figures")
    _add_launch_options(q)
    q.add_argument("--T", type=float, default=None, metavar="SECONDS",
                   help="duration (s) integrated and drawn (default: 20 s integrated for the "
                        "label, the first three orbits drawn, at most 36 theta cycles; the "
                        "line printed says how much was drawn)")
    q.add_argument("--dt", type=float, default=1e-4, metavar="SECONDS", help="largest step (s)")
    q.add_argument("--n-out", type=int, default=4001, metavar="N", help="samples kept")
    q.add_argument("--panels", choices=("all", "path"), default="all",
                   help="all: the path, theta, the rates, friction and normal force; path: the "
                        "path alone, in a small figure")
    q.add_argument("--dpi", type=int, default=100, metavar="N",
                   help="resolution of a PNG (dots per inch)")
    q.add_argument("-o", "--output", default="results/path.png", metavar="FILE",
                   help="figure file, .png, .pdf or .svg")
    q.add_argument("--show", metavar="POINTS",
                   help="also draw body points, comma-separated: face (centre of the flat face), "
                        "probe (its tip), contact (the contact point), as the paper's Fig. 4a")
    q.add_argument("--probe-m", type=float, default=0.0254, metavar="METRES",
                   help="probe length (m) on the flat face (the paper does not give it; one ball "
                        "radius)")
    q.add_argument("--forces", action="store_true",
                   help="also draw the net force (N) and torque about G (N m) against time, as "
                        "the paper's Figs. 4b, 7b, into FILE-forces (FILE's suffix)")
    _add_rolling_option(q)
    _add_ball_options(q)
    return q
