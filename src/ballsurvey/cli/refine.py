"""`ballsurvey refine`: a map refined near regime boundaries."""
from __future__ import annotations

from .options import UserError, _launch_opt, _opt, _out_file


def run(args):
    from .. import limits
    from ..refine import compare_with_full

    for name, launch_name in (("--theta0", "theta0_deg"), ("--chidot0", "chidot0")):
        lo, hi = (_launch_opt(name, launch_name, v) for v in getattr(args, name[2:]))
        if not lo < hi:
            raise UserError(f"{name}: must have LO < HI, got {lo:g} {hi:g}")
    _launch_opt("--phidot0", "phidot0", args.phidot0)
    coarse = _opt("--coarse", args.coarse, integer=True, lo=2, hi=10**5)
    levels = _opt("--levels", args.levels, integer=True, lo=0, hi=30)
    side = (coarse - 1) * 2**levels + 1
    try:
        limits.launches((side, side), "--coarse/--levels")
        limits.steps(args.T, 2e-4, "--T", "--T (at refine's step of 2e-4 s)")
    except limits.InputError as exc:
        raise UserError(str(exc)) from None
    out = _out_file("-o/--output", args.output, ".nc")
    import time

    from ..refine import refine_plane

    t0 = time.perf_counter()  # compile the kernels first, so the timings compare the work only
    refine_plane(tuple(args.theta0), tuple(args.chidot0), n_coarse=2, levels=0,
                 phidot0=args.phidot0, T=min(args.T, 0.05))
    from ..compose import warm_up_fallback

    warm_up_fallback()
    print(f"kernels ready ({time.perf_counter() - t0:.1f} s, not counted below)", flush=True)
    res = compare_with_full(tuple(args.theta0), tuple(args.chidot0), n_coarse=args.coarse,
                            levels=args.levels, phidot0=args.phidot0, T=args.T)
    if out is not None:
        _write_refined(out, res, args)
        print(f"wrote {out}")


def _write_refined(out, res, args) -> None:
    """The refined label map as a CF netCDF file (label with flag_values/flag_meanings)."""
    import numpy as np
    import xarray as xr

    from ..store import CONVENTIONS, REFERENCES, variable_attrs

    ref = res["refined"]
    ds = xr.Dataset(
        {"label": (("theta0_deg", "chidot0"), np.asarray(ref["label"], dtype=np.int8),
                   variable_attrs("label"))},
        coords={"theta0_deg": ("theta0_deg", ref["theta0_deg"],
                               {"units": "degree", "long_name": "initial tilt (theta0)"}),
                "chidot0": ("chidot0", ref["chidot0"],
                            {"units": "rad s-1", "long_name": "initial precession rate"}),
                "phidot0": ((), float(args.phidot0),
                            {"units": "rad s-1", "long_name": "initial spin rate"}),
                # refine launches with no tilt rate: said, so the map names whole launches
                "thetadot0": ((), 0.0, {"units": "rad s-1", "long_name": "initial tilt rate"})},
        attrs={"Conventions": CONVENTIONS, "title": "refined regime map (ballsurvey refine)",
               "references": REFERENCES, "run_T_s": float(args.T),
               "refine_coarse": int(args.coarse), "refine_levels": int(args.levels),
               "refine_integrated": int(res["integrated"]), "refine_full": int(res["full"]),
               "refine_agreement": float(res["agreement"]),
               "comment": "labels of cells whose corners agreed are filled, not integrated"})
    ds["label"].encoding["_FillValue"] = None
    out.parent.mkdir(parents=True, exist_ok=True)
    ds.to_netcdf(out)


def add_parser(cmd):
    """`ballsurvey refine`'s parser, made by `cmd` (`build_parser`'s)."""
    rf = cmd("refine", help="refine a (theta0, chidot0) map only near regime boundaries and "
                            "compare it with the full fine grid")
    rf.add_argument("--theta0", type=float, nargs=2, default=(-10.0, 30.0), metavar=("LO", "HI"),
                    help="range of the initial tilt (deg)")
    rf.add_argument("--chidot0", type=float, nargs=2, default=(1.0, 12.0), metavar=("LO", "HI"),
                    help="range of the initial precession rate (rad/s)")
    rf.add_argument("--phidot0", type=float, default=-3.0, metavar="RATE",
                    help="initial spin rate (rad/s)")
    rf.add_argument("--coarse", type=int, default=9, metavar="N", help="coarse grid size per side")
    rf.add_argument("--levels", type=int, default=4, metavar="N", help="halvings of the spacing")
    rf.add_argument("--T", type=float, default=20.0, metavar="SECONDS",
                    help="longest integration (s)")
    rf.add_argument("-o", "--output", metavar="FILE.nc",
                    help="also write the refined label map (netCDF; plot and query read it)")
    return rf
