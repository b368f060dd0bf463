"""`ballsurvey fit`: the launch that reproduces a measured track."""
from __future__ import annotations

from .options import _add_ball_options, _ball_arg, _opt, _out_file


def run(args):
    import json

    from ..fit import PARAMS, SLOWING, UNITS, fit_track, plot_fit, read_track

    out = _out_file("-o/--output", args.output, ".png")
    probe = _opt("--probe-m", args.probe_m, positive=True, hi=1.0)
    ball = _ball_arg(args)
    track = read_track(args.track, probe_m=probe, units=args.units, time_units=args.time_units)
    fit = fit_track(track, ball, slowing=args.slowing)
    params = PARAMS + (SLOWING,) * args.slowing
    # the numbers first: a plot that cannot be written (exit 1) leaves them printed
    if args.format == "json":
        keys = [k for p in params for k in (p, p + "_err")] + ["rms_m", "label", "status"]
        keys += [k for k in ("alternatives", "evidence", "reasons") if k in fit]
        keys += ["heading_deg", "heading_deg_err", "noise_m", "notes", "n_dropped", "dropped_t"]
        print(json.dumps({k: fit[k] for k in keys}), flush=True)
    else:
        print(f"status      {fit['status']}")
        for why in fit.get("reasons", []):
            print(f"  failed: {why}")
        for k in params:
            print(f"{k:11s} {fit[k]:+.6g} +- {fit[k + '_err']:.2g} {UNITS[k]}")
        print(f"heading     {fit['heading_deg']:+.4g} +- {fit['heading_deg_err']:.2g} deg "
              "(G's initial velocity, from the track's x axis)")
        print(f"rms_m       {fit['rms_m']:.3g} m (position residual per coordinate; the "
              f"track's noise {fit['noise_m']:.2g} m)")
        print(f"label       {fit['label']}")
        for a in fit.get("alternatives", []):
            print(f"  also fits: theta0 {a['theta0_deg']:+.4g} deg, thetadot0 "
                  f"{a['thetadot0']:+.4g}, chidot0 {a['chidot0']:+.4g}, phidot0 "
                  f"{a['phidot0']:+.4g} rad/s, chi0 {a['chi0_deg']:+.4g} deg: rms "
                  f"{a['rms_m']:.3g} m, {a['label']}")
        if "evidence" in fit:
            ev = fit["evidence"]
            print(f"  mismatch: rms/noise {ev['rms_over_noise']:.2f} "
                  f"(z {ev['rms_over_noise_z']:.1f}), "
                  f"runs z {ev['runs_z']:.1f}, lag-1 autocorrelation {ev['autocorrelation']:.2f}")
        for note in fit["notes"]:
            print(f"  note: {note}")
        if fit["n_dropped"]:
            ts = ", ".join(f"{t:g}" for t in fit["dropped_t"][:10])
            more = " ..." if len(fit["dropped_t"]) > 10 else ""
            untimed = fit["n_dropped"] - len(fit["dropped_t"])  # whose t itself is the bad cell
            where = "; ".join(w for w in (f"at t = {ts}{more} s" if ts else "",
                                          f"{untimed} with no time" if untimed > 0 else "") if w)
            print(f"dropped     {fit['n_dropped']} rows with a blank or non-finite cell "
                  f"({where})")
        print(f"({fit['n_samples']} samples, {fit['survey_launches']} launches surveyed, "
              f"{fit['seconds']:.1f} s)", flush=True)
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        plot_fit(track, fit, out, ball=ball)
        if args.format != "json":
            print(f"wrote {out}")


def add_parser(cmd):
    """`ballsurvey fit`'s parser, made by `cmd` (`build_parser`'s)."""
    ft = cmd("fit", help="find the launch that reproduces a measured track (CSV, Tracker's "
                         "export)")
    ft.add_argument("track", metavar="TRACK.csv",
                    help="header row (a name line above it is skipped) and columns t (s) and "
                         "x, y (m, centre of mass), or two tracked masses named tip and base, or "
                         "x_tip, y_tip, x_base, y_base (m, with --probe-m); optionally theta_deg "
                         "(deg) and chidot (rad/s); tab, comma or semicolon separated; rows with "
                         "a blank or non-finite cell dropped")
    ft.add_argument("--units", choices=("m", "cm", "mm"),
                    help="length unit of the positions (default: the header's, 'x (cm)', or m)")
    ft.add_argument("--time-units", choices=("s", "ms"),
                    help="time unit of t (default: the header's, 't (ms)', or s)")
    ft.add_argument("--probe-m", type=float, metavar="METRES",
                    help="probe length (m), for a track of the probe's tip and base")
    ft.add_argument("-o", "--output", metavar="FILE.png", help="also draw track and fit (PNG)")
    ft.add_argument("--slowing", action="store_true",
                    help="the ball slows (every real ball on a real table does): fit the "
                         "rolling-resistance coefficient (dimensionless, as path's "
                         "--rolling-resistance) with the launch; the output gains "
                         "rolling_resistance and its _err")
    ft.add_argument("--format", choices=("text", "json"), default="text",
                    help="json: keys theta0_deg, thetadot0, chidot0, phidot0, chi0_deg, x0, y0 "
                         "(deg, rad/s, m; each with _err, one standard deviation), with "
                         "--slowing rolling_resistance (1) and its _err, rms_m, label, "
                         "status (ok, ambiguous, mismatch, failed), alternatives, evidence, "
                         "reasons (where they apply), heading_deg, noise_m, notes, n_dropped, "
                         "dropped_t")
    _add_ball_options(ft)
    return ft
