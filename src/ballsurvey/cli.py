"""Command line: `ballsurvey <command>` (or `python -m ballsurvey <command>`).

Exit status: 0 done; 2 an input error (`ballsurvey.limits.InputError`, raised by validation code:
one line on stderr, nothing written); 1 a run that failed for a reason outside its input
(`RunError`, or the system refused a file operation: one line); 130 interrupted (Ctrl-C). Any
other exception is a bug and shows its traceback.
"""
from __future__ import annotations

import argparse
import math
import sys
from contextlib import contextmanager

from .limits import InputError


class UserError(InputError):
    """A problem with the user's input: reported as one line, exit status 2."""


def _opt(name, value, **rules):
    """A numeric option by the shared rules of `ballsurvey.limits`; UserError naming it."""
    from . import limits

    if value is None:
        return None
    try:
        return limits.number(name, value, **rules)
    except limits.InputError as exc:
        raise UserError(str(exc)) from None


def _launch_opt(flag, name, value, ball=None):
    """A launch input option: theta0_deg inside the model's tilts (of `ball`, default the
    paper's), a rate or the heading within `limits.LAUNCH_BOUNDS`; UserError naming the flag."""
    import math

    from . import limits
    from .ball import Ball, tilt_error

    if value is None:
        return None
    try:
        if name != "theta0_deg":
            return limits.launch_value(name, value, flag)
        value = limits.number(flag, value)
    except limits.InputError as exc:
        raise UserError(str(exc)) from None
    problem = tilt_error(value, math.degrees((ball or Ball.paper()).flat_face_theta_rad))
    if problem:
        raise UserError(f"{flag}: {problem}")
    return value


def _out_file(name, value, suffix):
    """-o/--output: a file name ending in `suffix` (a string, or a tuple of those allowed) that
    is not an existing folder."""
    from pathlib import Path

    if value is None:
        return None
    suffixes = (suffix,) if isinstance(suffix, str) else tuple(suffix)
    p = Path(value)
    ok = any(p.name.lower().endswith(s) and p.name.lower() != s for s in suffixes)
    want = " or ".join(suffixes)
    if not value or not ok:
        raise UserError(f"{name}: must be a file name ending in {want}, got {value!r}")
    if p.is_dir():
        raise UserError(f"{name}: {value} is a folder; give a file name ending in {want}")
    _check_writable(name, p.parent)
    return p


def _figure_file(value):
    """-o/--output of a figure command: .png, .pdf or .svg."""
    from .plot import FIGURE_SUFFIXES

    return _out_file("-o/--output", value, FIGURE_SUFFIXES)


#: the order of `ballsurvey --help`: what a user does first comes first
COMMAND_ORDER = ("path", "sweep", "plot", "query", "find", "explore", "animate", "fit", "gallery",
                 "refine", "paper", "accuracy", "bench")
#: path's integration time (s) when --T is not given: long enough for the label on most launches
PATH_T = 20.0
#: what `bench --scaling` holds when given without a spec (then --headline names the map)
SCALING_HEADLINE = "(the headline map)"


def _check_writable(name, folder) -> None:
    """Refuse (one line, exit 2, before any work) an output folder that cannot be written: the
    nearest folder of it that exists must take a new file (tried, and removed at once)."""
    import os
    import tempfile
    from pathlib import Path

    d = Path(os.path.abspath(folder))
    while not d.exists() and d != d.parent:
        d = d.parent
    if not d.is_dir():
        raise UserError(f"{name}: {d} is a file, not a folder")
    try:
        fd, probe = tempfile.mkstemp(prefix=".ballsurvey-probe-", dir=d)
    except OSError as exc:
        raise UserError(f"{name}: cannot write in {d}: {exc.strerror}") from None
    os.close(fd)
    os.unlink(probe)


def _check_bench(args):
    """Every bench option by the shared rules, before anything is compiled or timed."""
    from . import limits

    modes = [f for f in ("map", "spec", "scaling", "period", "headline")
             if getattr(args, f) is not None]
    if modes[:2] == ["scaling", "headline"]:  # the scaling bench on the headline map
        modes = modes[:1] + modes[2:]
    if len(modes) > 1:
        raise UserError(f"--{modes[0]} and --{modes[1]} are two benchmarks: give one")
    for name in ("map", "period", "headline"):
        _opt(f"--{name}", getattr(args, name), integer=True, lo=1, hi=10**4)
    _opt("--launches", args.launches, integer=True, lo=1, hi=10**8)
    _opt("--steps", args.steps, integer=True, lo=1, hi=10**8)
    _opt("--repeats", args.repeats, integer=True, lo=1, hi=1000)
    _opt("--block", args.block, integer=True, lo=1, hi=limits.MAX_BLOCK)
    _opt("--observe-every", args.observe_every, integer=True, lo=1, hi=limits.MAX_OBSERVE_EVERY)
    _opt("--dt", args.dt, positive=True)
    _opt("--T", args.T, positive=True, hi=limits.MAX_DURATION_S)
    for name in ("threads", "workers"):
        _opt(f"--{name}", getattr(args, name), integer=True, lo=1, hi=limits.MAX_WORKERS)
    if args.spec == "":
        raise UserError("--spec: give a spec file (.toml)")
    if args.scaling == "" or (args.scaling == SCALING_HEADLINE and args.headline is None):
        raise UserError("--scaling: give a spec file (.toml), or --headline [N]")
    if args.scaling not in (None, SCALING_HEADLINE) and args.headline is not None:
        raise UserError("--scaling: give a spec file (.toml) or --headline [N], not both")


def _cmd_bench(args):
    from .bench import run_bench, run_map_bench

    _check_bench(args)
    if args.scaling is None and (args.threads is not None or args.workers is not None):
        raise InputError("--threads and --workers go with --scaling SPEC.toml or --scaling "
                         "--headline [N]")

    if args.map is not None:
        run_map_bench(n=args.map, T=args.T, dt=args.dt)
        return
    if args.spec:
        from .bench import run_spec_bench

        run_spec_bench(args.spec)
        return
    if args.scaling is not None:
        from .bench import run_scaling

        headline = args.scaling == SCALING_HEADLINE
        run_scaling(None if headline else args.scaling, threads=args.threads,
                    workers=args.workers, headline=args.headline if headline else None,
                    T=args.T, method=args.method or "dop853")
        return
    if args.period is not None:
        from .bench import run_period_bench

        run_period_bench(n=args.period, T=args.T)
        return
    if args.headline is not None:
        from .bench import run_headline

        method = args.method or ("rk4" if args.backend == "cuda" else "dop853")
        if args.backend == "cuda":
            from .integrate.tableaus import FIXED_STEP

            if method not in FIXED_STEP and method != "quadrature":
                raise InputError(f"--headline --backend cuda runs rk4 or quadrature, not {method}")
            _check_cuda()
        run_headline(n=args.headline, T=args.T, method=method, backend=args.backend)
        return
    if args.backend == "cuda":
        from .bench import run_bench_cuda

        _check_cuda()
        run_bench_cuda(n_launches=args.launches, n_steps=args.steps, dt=args.dt,
                       repeats=args.repeats, observe_every=args.observe_every)
        return
    run_bench(n_launches=args.launches, n_steps=args.steps, dt=args.dt, repeats=args.repeats,
              block=args.block, observe_every=args.observe_every)


def _check_cuda() -> None:
    """One line (exit 2) before anything is written when the CUDA backend cannot run here."""
    from .integrate.cuda import BackendError, cuda_module

    try:
        cuda_module()
    except BackendError as exc:
        raise UserError(f"backend cuda: {exc}") from None


def _cmd_sweep(args):
    import shlex
    import time
    from dataclasses import replace

    from . import limits
    from .sweep import SweepInterrupted, load_spec, run_sweep
    from .sweep.engine import UpToDate, check_output_path, dask_client
    from .sweep.parts import existing_output, tidy_finished

    out = _out_file("-o/--output", args.output, ".nc")
    chunk = args.chunk
    if chunk is not None:
        chunk = limits.chunk_size(chunk, "--chunk")
    if args.workers is not None:
        limits.workers(args.workers)
    if args.scheduler is not None:
        limits.scheduler(args.scheduler)
    wait_s = _opt("--dask-timeout", args.dask_timeout, positive=True, hi=86400)
    spec = load_spec(args.spec, run={"backend": args.backend} if args.backend else None)
    if out is not None:
        spec = replace(spec, output=out)
    if chunk is not None:
        spec = replace(spec, chunk=chunk)
    check_output_path(spec.output)
    limits.chunk_plan(spec.shape, spec.chunk, "--chunk" if chunk is not None else "chunk")
    if spec.backend == "cuda":
        _check_cuda()

    verbosity = args.verbose - args.quiet
    progress = args.progress if args.progress is not None else (None if verbosity >= 0 else False)

    def notice(msg):
        if verbosity >= 0:
            print(f"ballsurvey sweep: {msg}", file=sys.stderr, flush=True)

    try:  # before any cluster starts: an existing map this run would not touch
        existing_output(spec, force=args.force)
    except UpToDate as exc:
        tidy_finished(spec, notice)
        print(exc)
        return

    last = [0.0]

    def on_unit(done, total):  # -v: a line per unit of work, at most two a second
        now = time.monotonic()
        if verbosity >= 1 and (now - last[0] >= 0.5 or done == total):
            last[0] = now
            print(f"ballsurvey sweep: {done} of {total} launches done", file=sys.stderr,
                  flush=True)

    command = "ballsurvey " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    report: dict = {}
    if verbosity >= 1:
        print(f"ballsurvey sweep: {spec.n_launches} launches ({' x '.join(map(str, spec.shape))})"
              f" -> {spec.output}", file=sys.stderr, flush=True)
    if (args.scheduler or args.workers) and verbosity < 2:
        _quiet_dask()
    if not (args.scheduler or args.workers):
        report["numba_start_s"] = _start_numba()
    try:
        t_cluster = time.perf_counter()
        with dask_client(args.scheduler, args.workers, wait_s) as client:
            report["cluster_start_s"] = time.perf_counter() - t_cluster
            report["cluster_start"] = "connection" if args.scheduler else "cluster start"
            written = run_sweep(spec, resume=args.resume, force=args.force, client=client,
                                progress=progress, command=command, dask_wait_s=wait_s,
                                notice=notice, on_unit=on_unit, report=report)
            t_cluster = time.perf_counter()
        report["cluster_close_s"] = time.perf_counter() - t_cluster
    except KeyboardInterrupt as exc:  # the run's own account, or one of the saved parts
        _ignore_more_ctrl_c()
        again = " ".join(shlex.quote(a) for a in sys.argv[1:] if a != "--resume")
        if isinstance(exc, SweepInterrupted):
            kept = f"{exc.kept} of {exc.total} launches are saved in {exc.parts}"
        else:  # before the run started (a cluster starting) or after it ended
            from .sweep.engine import parts_dir

            parts = parts_dir(spec.output)
            n = len(list(parts.glob("*.npz"))) if parts.is_dir() else 0
            if not n:
                print("ballsurvey sweep: interrupted before any launch was saved",
                      file=sys.stderr)
                raise SystemExit(130) from None
            kept = f"the {n} saved parts in {parts} are kept"
        print(f"ballsurvey sweep: interrupted; {kept}: run `ballsurvey {again} --resume` to "
              "continue", file=sys.stderr)
        raise SystemExit(130) from None
    if verbosity < 0:
        print(f"wrote {written}")
        return
    print(sweep_summary(written, spec.n_launches, report))
    if verbosity >= 1:
        print(_where_the_time_went(report, client is not None), file=sys.stderr)


def _where_the_time_went(report: dict, on_dask: bool) -> str:
    """`sweep -v`'s account of a run's time (s): numba's start (`_start_numba`), the kernels'
    phases (`compose.TIMES`: in this process, or on dask each worker's on average), the rest of
    the run, and on dask the cluster's start (or the connection to a running scheduler), the
    workers' first call and the client's (and a local cluster's) closing. `bench --scaling`
    reads it."""
    from .compose import TIMES, in_line, phases_text

    wall = report.get("wall_s", float("nan"))
    if on_dask:
        n = report.get("n_workers", 0)
        kernels = (f"; on each of the {n} workers, on average: "
                   f"{phases_text(report['worker_times'], per=n, beside=False)}" if n else "")
        start = report.get("cluster_start", "cluster start")
        return (f"  where the time went: dask {start} {report['cluster_start_s']:.2f} s, "
                f"workers' first call {report.get('workers_start_s', float('nan')):.2f} s "
                f"(imports, kernels loaded), the run on the cluster {wall:.2f} s, closing "
                f"{report.get('cluster_close_s', float('nan')):.2f} s{kernels}")
    comp = report.get("compile_s", 0.0)
    rest = wall - in_line(TIMES)
    # kernels compile at their first call, inside the phase that calls them
    comp = f"; {comp:.2f} s of it compiling kernels at first call" if comp >= 0.05 else ""
    start = (f"numba start {report['numba_start_s']:.2f} s (before the run), "
             if "numba_start_s" in report else "")
    return (f"  where the time went: {start}{phases_text(TIMES)}, the rest (plan, parts, "
            f"writing) {rest:.2f} s{comp}")


def _start_numba() -> float:
    """numba's CPU target started (its registries of typing and lowering, which import
    scipy.linalg for numba's linear algebra: about 0.2 s), as the first kernel call of a process
    would: once here, the kernels' times (`compose.TIMES`) leave it out. Returns its seconds."""
    import time

    t = time.perf_counter()
    try:
        from numba.core.registry import cpu_target

        cpu_target.target_context.refresh()
    except (ImportError, AttributeError):  # numba's internals moved: the first call does it
        pass
    return time.perf_counter() - t


def _quiet_dask() -> None:
    """dask's warnings in this process off (-vv keeps them): what they say that matters (a lost
    worker or scheduler) ends the run with one line of ours. "distributed" sets its loggers'
    levels when imported, so it is imported first. asyncio reports an abandoned fetch of a
    lost worker's result when the client closes ("Task exception was never retrieved"), and
    tornado a traceback from inside distributed when Ctrl-C lands in one of its waits: both
    after our line, and neither says anything to act on."""
    import logging
    import warnings

    import distributed  # noqa: F401

    from .sweep.executors import raise_log_levels

    # a Ctrl-C inside one of distributed's waits leaves a coroutine unawaited: Python warns
    for module in ("tornado", "distributed", "asyncio"):
        warnings.filterwarnings("ignore", category=RuntimeWarning, module=module)
    raise_log_levels(logging.CRITICAL)


def sweep_summary(path, n_launches: int, report: dict) -> str:
    """The end of a sweep in a few lines: time, rate, counts per label, flagged and fallback
    launches, and the commands to look at the map."""
    import netCDF4
    import numpy as np

    from .classify.labels import LABELS, SHAPES
    from .integrate.tableaus import LANE_ADAPTIVE

    wall = report.get("wall_s", float("nan"))
    comp = report.get("compile_s", 0.0)
    computed = report.get("computed", n_launches)
    rate = computed / max(wall - comp, 1e-9)
    head = f"wrote {path} ({n_launches} launches)"
    if computed:
        head += f" in {wall:.1f} s"
        head += f" ({comp:.1f} s of it compiling kernels)" if comp >= 0.05 else ""
        head += f", {rate:,.0f} launches/s"
    if report.get("resumed"):
        head += f", {report['resumed']} of them from the interrupted run"
    from .store import netcdf_lock

    # netCDF4 itself: a sweep from the command line then never imports xarray (0.25 s)
    with netcdf_lock(direct=True), netCDF4.Dataset(path) as nc:
        nc.set_auto_mask(False)
        attrs = nc.__dict__
        codes = nc.variables["label"][...].ravel()
        # the lane methods (dop853) integrate every launch in the fixed frame: no fallback
        by_design = attrs.get("run_method") in LANE_ADAPTIVE
        fallback = (int((nc.variables["formulation"][...] == 1).sum())
                    if "formulation" in nc.variables and not by_design else None)
        by_quadrature = attrs.get("run_method") == "quadrature"
        sparse = 0
        if "samples_per_cycle" in nc.variables:
            floor = float(attrs.get("classify_min_samples_per_cycle", 20.0))
            with np.errstate(invalid="ignore"):
                sparse = int(((nc.variables["samples_per_cycle"][...].ravel() < floor)
                              & (codes == LABELS.index("unresolved"))).sum())
        title = attrs.get("title", "")
        points = "launch" in nc.dimensions  # named points: a table, no plot
    counts = np.bincount(codes[(codes >= 0) & (codes < len(LABELS))].astype(int),
                         minlength=len(LABELS))
    shapes = ", ".join(f"{w} {counts[i]}" for i, w in enumerate(LABELS)
                       if w in SHAPES and counts[i])
    status = ", ".join(f"{w} {counts[i]}" for i, w in enumerate(LABELS)
                       if w not in SHAPES and counts[i])
    n_flag = int(sum(counts[i] for i, w in enumerate(LABELS) if w not in SHAPES))
    lines = [head + (f" ({title})" if title else ""),
             f"  shapes: {shapes or 'none'}",
             f"  flagged (a status instead of a shape): {n_flag}" + (f" ({status})" if status
                                                                     else "")]
    if sparse:
        lines.append(f"  unresolved for too few observer samples per theta cycle (under "
                     f"{floor:g}): {sparse}; lower [run] dt or observe_every (fixed step) or "
                     f"rtol (dop853)")
    if fallback is not None and by_quadrature:
        lines.append(f"  integrated (dop853) where the quadrature cannot go (tilt through the "
                     f"vertical, launched steady, not converged): {fallback}")
    elif fallback is not None:
        lines.append(f"  integrated again in the fixed frame (near the vertical): {fallback}")
    best = next((w for w in ("square", "triangle", "ngon", "star", "circle")
                 if counts[LABELS.index(w)]), None)
    steps = [] if points else [f"ballsurvey plot {path}"]
    if best:
        steps.append(f"ballsurvey query {path} --shape {best}")
    if steps:
        lines.append("  next: " + "   |   ".join(steps))
    return "\n".join(lines)


def _open_map(path):
    """A map for plot/query/gallery; one line (exit 2) for anything that is not one."""
    from .api import open_map

    return open_map(path)


def _parse_at(items):
    at = {}
    for item in items or []:
        key, sep, val = item.partition("=")
        if not sep or not key:
            raise UserError(f"--at takes AXIS=VALUE, got {item!r}")
        try:
            at[key] = float(val)
        except ValueError:
            raise UserError(f"--at {key}: {val!r} is not a number") from None
        _opt(f"--at {key}", at[key])
    return at


def _cmd_plot(args):
    from pathlib import Path

    from .api import select
    from .plot import plot_map

    out = _figure_file(args.output) or Path(args.result).with_suffix(".png")
    at = _parse_at(args.at)
    ds = _open_map(args.result)
    plot_map(ds, out, x=args.x, y=args.y, at=at, facet=args.facet,
             contours=not args.no_contours)
    for key, asked in at.items():
        used = float(select(ds[[key]], **{key: asked})[key])
        if used != asked:
            print(f"--at {key}={asked:g}: drew the map's nearest value, {key} = {used:g}")
    print(f"wrote {out}")


def _cmd_explore(args):
    from .explore import require_bokeh

    require_bokeh()
    port = _opt("--port", args.port, integer=True, lo=1, hi=65535)
    at = _parse_at(args.at)
    if args.html is not None:
        from .explore import write_html

        if args.allow_host:
            raise UserError("--allow-host is for the app; a static page (--html) is served by "
                            "no one")
        out = _out_file("--html", args.html, ".html")
        r = write_html(args.result, out, x=args.x, y=args.y, at=at)
        paths = "with paths" if r["paths"] else "without paths (slice too large)"
        print(f"wrote {out} ({r['launches']} launches shown, {paths})")
        return
    from .explore import host_names, serve

    extra = host_names(args.allow_host or [], int(port))
    if extra:
        print(f"warning: --allow-host: the app also answers {', '.join(extra)}: whoever reaches "
              "it by that name can drive it and read the map", file=sys.stderr, flush=True)
    serve(args.result, port=int(port), open_browser=not args.no_browser, x=args.x, y=args.y,
          at=at, ready=lambda line: print(line, flush=True), allow_hosts=extra)


def _cmd_path(args):
    from . import limits
    from .plot import (
        BODY_POINTS,
        cycles_per_orbit,
        is_steady,
        orbit_window,
        plot_forces,
        plot_path,
        shape_text,
    )
    from .simulate import check_simulate_inputs, simulate

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
        from .classify.labels import Thresholds

        turn = (f"steady (theta stays within {Thresholds().steady_theta_tol_deg:g} deg: no theta "
                "cycle, no turn per cycle)")
    elif math.isfinite(float(a["turn_per_cycle_deg"])):
        turn = f"turn per cycle {a['turn_per_cycle_deg']:.3f} deg"
    else:
        turn = f"no turn per cycle (too few theta cycles in {T:g} s)"
    print(f"{shape_text(a)}; {turn}, theta {a['theta_min_deg']:.2f}..{a['theta_max_deg']:.2f} "
          f"deg (label from {T:g} s){shown}; wrote {out}")


def _ball_arg(args):
    """The ball of --ball / --cut-height / --spec (`sweep.spec.ball_from_options`)."""
    from .sweep.spec import ball_from_options

    cut = _opt("--cut-height", args.cut_height, nonnegative=True)
    return ball_from_options(args.ball, cut, args.spec)


def _add_launch_options(parser) -> None:
    """One launch's options (path, animate): tilt and heading in deg, rates in rad/s."""
    parser.add_argument("--theta0-deg", type=float, required=True, metavar="DEG",
                        help="initial tilt (deg)")
    parser.add_argument("--thetadot0", type=float, default=0.0, metavar="RATE",
                        help="initial tilt rate (rad/s)")
    parser.add_argument("--chidot0", type=float, required=True, metavar="RATE",
                        help="initial precession rate (rad/s)")
    parser.add_argument("--phidot0", type=float, required=True, metavar="RATE",
                        help="initial spin rate (rad/s)")
    parser.add_argument("--chi0-deg", type=float, default=0.0, metavar="DEG",
                        help="initial heading (deg)")


def _add_rolling_option(parser) -> None:
    """--rolling-resistance of a command that integrates one launch (path, animate)."""
    parser.add_argument("--rolling-resistance", type=float, default=0.0, metavar="MU",
                        help="rolling-resistance coefficient mu_r (dimensionless: the lever arm "
                             "of the couple mu_r N a that opposes the rolling, over the ball's "
                             "radius a; 0.001-0.02 on a table); 0: none, as the paper. Above 0 "
                             "the launch is integrated in the fixed frame by dopri5")


def _rolling_opt(args) -> float:
    from . import limits

    return _opt("--rolling-resistance", args.rolling_resistance, nonnegative=True,
                hi=limits.MAX_ROLLING_RESISTANCE)


def _add_drawn_axes_options(parser) -> None:
    """--x and --y of a command that draws a map (plot, explore): both choose alike."""
    parser.add_argument("--x", metavar="AXIS",
                        help="axis drawn across (default: the map's first axis with more than "
                             "one value, in its order theta0_deg, thetadot0, chidot0, phidot0, "
                             "...)")
    parser.add_argument("--y", metavar="AXIS",
                        help="axis drawn up (default: the next axis with more than one value)")


def _add_ball_options(parser, default="the paper's truncated billiard ball") -> None:
    g = parser.add_argument_group(f"the ball (default: {default})")
    g.add_argument("--ball", metavar="K=V,...",
                   help="the ball as a spec's [ball] gives it, SI: a=..,c=..,M=..,A=..,B=.. "
                        "(m, m, kg, kg m^2, kg m^2; also g=, cut_height=) or a=..,cut_height=..,"
                        "M=.. for a truncated uniform sphere")
    g.add_argument("--cut-height", type=float, metavar="METRES",
                   help="height (m) of the cap cut off: alone, from the paper's sphere (a = 25.4 "
                        "mm, M = 98.4 g), c, A, B from the geometry; with --ball, its cap")
    g.add_argument("--spec", metavar="SPEC.toml", help="use the [ball] of this sweep spec")


def _cmd_animate(args):
    from . import limits
    from .animate import check_output, frame_count, write_animation
    from .simulate import check_simulate_inputs, simulate

    ball = _ball_arg(args)
    for name in ("theta0_deg", "thetadot0", "chidot0", "phidot0", "chi0_deg"):
        _launch_opt("--" + name.replace("_", "-"), name, getattr(args, name), ball)
    fps = _opt("--fps", args.fps, lo=1, hi=120)  # a GIF frame lasts at most 655 s
    speed = _opt("--speed", args.speed, positive=True, hi=100)
    probe = _opt("--probe-m", args.probe_m, nonnegative=True, hi=1.0)
    mu_r = _rolling_opt(args)
    try:
        out = check_output(args.output)
    except limits.InputError as exc:
        raise UserError(f"-o/--output: {exc}") from None
    _check_writable("-o/--output", out.parent)
    try:
        limits.steps(args.T, args.dt, "--T", "--dt")
        check_simulate_inputs(args.theta0_deg, args.thetadot0, args.chidot0, args.phidot0, args.T,
                              args.dt, args.chi0_deg, ball=ball)
        frames = frame_count(args.T, fps, speed)
        n_out = int(min(max(round(args.T / args.dt), 1), 20000)) + 1
        ds = simulate(args.theta0_deg, args.thetadot0, args.chidot0, args.phidot0, args.T,
                      dt=args.dt, chi0_deg=args.chi0_deg, n_out=n_out, ball=ball, probe_m=probe,
                      rolling_resistance=mu_r)
    except limits.InputError as exc:
        raise UserError(str(exc)) from None
    write_animation(ds, out, ball=ball, fps=fps, speed=speed)
    print(f"{ds.attrs['label']}: wrote {out} ({frames} frames, {fps:g} fps, {speed:g}x speed)")


def _cmd_fit(args):
    import json

    from .fit import PARAMS, SLOWING, UNITS, fit_track, plot_fit, read_track

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
            print(f"dropped     {fit['n_dropped']} rows with a blank or NaN cell "
                  f"(t = {ts}{more} s)")
        print(f"({fit['n_samples']} samples, {fit['survey_launches']} launches surveyed, "
              f"{fit['seconds']:.1f} s)", flush=True)
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        plot_fit(track, fit, out, ball=ball)
        if args.format != "json":
            print(f"wrote {out}")


def _cmd_query(args):
    from .query import DEFAULT_LIMIT, format_table, query

    limit = _opt("--limit", args.limit, integer=True, lo=1)
    if limit is None and not args.all:
        limit = DEFAULT_LIMIT
    _opt("--n-sides", args.n_sides, integer=True, lo=3)
    df = query(_open_map(args.result), shape=args.shape, n_sides=args.n_sides, limit=limit,
               max_n_error=args.max_n_error, max_closure=args.max_closure)
    print(format_table(df, args.format), flush=True)
    more = df.attrs["matched"] - len(df)
    if more > 0:
        print(f"... {more} more matched (--limit N or --all to see more)", file=sys.stderr)


def _cmd_gallery(args):
    from pathlib import Path

    from .gallery import draw_gallery

    _opt("--per-label", args.per_label, integer=True, lo=1, hi=100)
    _opt("--seed", args.seed, integer=True, lo=0, hi=2**32 - 1)
    _opt("--T", args.T, positive=True, hi=1e6)
    ds = _open_map(args.result)  # a folder or '.' is refused here, before naming the output
    out = _figure_file(args.output or str(Path(args.result).with_name(
        Path(args.result).stem + "-gallery.png")))
    rows = draw_gallery(ds, out, per_label=args.per_label, seed=args.seed, T=args.T,
                        ball=_ball_arg(args) if (args.ball or args.cut_height is not None
                                                 or args.spec) else None)
    changed = [r for r in rows if r["label_again"] != r["label"]]
    print(f"wrote {out}: {len(rows)} paths, "
          f"{len(changed)} labelled differently when integrated again")


def _cmd_accuracy(args):
    if args.ensemble is not None:
        from .accuracy import ensemble_work_precision

        if args.ensemble < 1:
            raise UserError(f"--ensemble needs at least 1 launch, got {args.ensemble}")
        ensemble_work_precision(n=args.ensemble)
        return
    from .accuracy import run_accuracy

    _check_writable("-o/--output", args.output)
    run_accuracy(args.output, quick=args.quick, fig_format=args.format)


def _cmd_find(args):
    import numpy as np

    from . import limits
    from .find import SHAPE_OF_N, NoSolution, find_launch, trace

    _opt("--n-sides", args.n_sides, integer=True, lo=3, hi=1000)
    ball = _ball_arg(args)
    for name in ("theta0_deg", "thetadot0", "chidot0", "phidot0"):
        _launch_opt("--" + name.replace("_", "-"), name, getattr(args, name), ball)
    if args.bracket:
        # a theta0 bracket may reach past the model's tilts: the scan skips what it cannot take
        lo, hi = (_opt("--bracket", v) if args.solve == "theta0_deg"
                  else _launch_opt("--bracket", args.solve, v) for v in args.bracket)
        if not lo < hi:
            raise UserError(f"--bracket: must have LO < HI, got {lo:g} {hi:g}")
    if args.output is not None and not args.trace_theta0:
        raise UserError("-o/--output goes with --trace-theta0 (one solve prints its roots)")
    out = _out_file("-o/--output", args.output, ".csv")
    if args.trace_theta0:
        start, stop = (_launch_opt("--trace-theta0", "theta0_deg", v, ball)
                       for v in args.trace_theta0[:2])
        _opt("--trace-theta0 NUM", args.trace_theta0[2], integer=True, lo=1,
             hi=min(limits.MAX_LAUNCHES, 10**5))
    polygons = {"triangle": 3, "square": 4, "pentagon": 5, "hexagon": 6, "heptagon": 7,
                "octagon": 8, "nonagon": 9, "decagon": 10}
    if args.shape and args.shape not in ("triangle", "square"):
        n_named = polygons.get(args.shape.lower())
        hint = f"use --n-sides {n_named}" if n_named else "use --n-sides N for other polygons"
        raise UserError(f"--shape {args.shape}: --shape takes triangle or square; {hint}")
    n = args.n_sides or polygons.get(args.shape or "")
    if not n:
        raise UserError("give --shape triangle|square or --n-sides N")
    launch = dict(theta0_deg=args.theta0_deg, thetadot0=args.thetadot0, chidot0=args.chidot0,
                  phidot0=args.phidot0)
    if args.trace_theta0:
        import time

        if args.phidot0 is None:
            raise UserError("give --phidot0 (--trace-theta0 traces theta0 and solves chidot0)")
        start, stop, num = args.trace_theta0
        t0 = time.perf_counter()
        rows = trace(n, np.linspace(start, stop, int(num)), launch, args.bracket, ball=ball)
        took = time.perf_counter() - t0
        lines = ["theta0_deg,chidot0_rad_s,n_sides_integrated,closure_m,label,shape"] + [
            f"{th:.6g},{s.value:.9g},{s.n_sides:.9f},{s.closure_m:.2e},{s.label},{s.shape}"
            for th, s in rows]
        if out is not None:
            out.write_text("\n".join(lines) + "\n")
            print(f"wrote {len(rows)} points of the n = {n} curve to {args.output} "
                  f"({took:.1f} s, each checked by integration)")
        else:
            print("\n".join(lines))
        return
    missing = [k for k, v in launch.items() if v is None and k != args.solve]
    if missing:
        flag = missing[0].replace("_", "-")
        raise UserError(f"give --{flag} (only --solve {args.solve} is free)")
    launch = {k: (0.0 if v is None else v) for k, v in launch.items()}
    rejected: list = []
    try:
        sols = find_launch(n, launch, args.solve, args.bracket, ball=ball, rejected=rejected)
    except NoSolution as exc:
        print(f"ballsurvey find: no solution: {exc}", file=sys.stderr)
        raise SystemExit(1) from None
    unit = "deg" if args.solve == "theta0_deg" else "rad/s"
    for s in sols:
        called = "" if s.label == SHAPE_OF_N.get(n, "ngon") else f" (labelled {s.label})"
        print(f"{s.variable} = {s.value:.10g} {unit}: integrated (adaptive, rtol 1e-10): "
              f"{s.shape}{called}, roundness {s.roundness:.3f}, {s.corner_kind} corners, "
              f"n_sides = {s.n_sides:.9f}, turn per cycle "
              f"{s.turn_per_cycle_deg:.7f} deg, theta period {s.theta_period_s:.6f} s, "
              f"closure {s.closure_m:.2e} m per circuit")
    for s in rejected:
        print(f"not a solution: {s.variable} = {s.value:.10g} {unit} turns 360/{n} deg per cycle "
              f"but integrates as {s.label} (n_sides = {s.n_sides:.6f}, roundness "
              f"{s.roundness:.3f}, {s.corner_kind} corners)")


def _cmd_refine(args):
    from . import limits
    from .refine import compare_with_full

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

    from .refine import refine_plane

    t0 = time.perf_counter()  # compile the kernels first, so the timings compare the work only
    refine_plane(tuple(args.theta0), tuple(args.chidot0), n_coarse=2, levels=0,
                 phidot0=args.phidot0, T=min(args.T, 0.05))
    from .compose import warm_up_fallback

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

    from .store import CONVENTIONS, REFERENCES, variable_attrs

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


def _cmd_paper(args):
    from .paper import reproduce

    _check_writable("-o/--output", args.output)
    reproduce(args.output, fig_format=args.format)


def _version() -> str:
    """The installed distribution's version; the package's own when run from a source tree."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("ballsurvey")
    except PackageNotFoundError:
        from . import __version__

        return __version__


class _Help(argparse.HelpFormatter):
    """Shows each option's default after its help, unless it has none (None or a bare flag)."""

    def _get_help_string(self, action):
        h = action.help or ""
        d = action.default
        if (d is None or d is False or d is argparse.SUPPRESS or "default" in h
                or not action.option_strings
                or isinstance(action, (argparse._VersionAction, argparse._CountAction))):
            return h
        d = " ".join(f"{v:g}" if isinstance(v, float) else str(v) for v in d) \
            if isinstance(d, (list, tuple)) else (f"{d:g}" if isinstance(d, float) else d)
        return f"{h} (default: {d})"


class _Parser(argparse.ArgumentParser):
    """argparse with its errors on one line (exit 2), like every other input error."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (--help lists the options)\n")


def build_parser() -> argparse.ArgumentParser:
    ap = _Parser(prog="ballsurvey", formatter_class=_Help,
                                 description="Map how a biased ball rolls (Wheatland, Cross et al. "
                                             "2020). Exit status: 0 done, 1 run failed, 2 input "
                                             "error, 130 interrupted.")
    ap.add_argument("--version", action="version", version=f"ballsurvey {_version()}")
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND")
    ap.commands = sub.choices  # each command's own parser, by name

    def cmd(name, **kw):
        return sub.add_parser(name, formatter_class=_Help, **kw)

    b = cmd("bench", help="IC-steps/s of the ensemble kernel vs a naive per-launch loop")
    b.add_argument("--launches", type=int, default=4096, metavar="N",
                   help="launches integrated at once")
    b.add_argument("--steps", type=int, default=2000, metavar="N", help="RK4 steps per launch")
    b.add_argument("--dt", type=float, default=1e-4, metavar="SECONDS", help="step (s)")
    b.add_argument("--repeats", type=int, default=3, metavar="N",
                   help="timed repetitions (the best is reported)")
    b.add_argument("--block", type=int, default=64, metavar="N", help="launches per SIMD block")
    b.add_argument("--backend", choices=("cpu", "cuda"), default="cpu",
                   help="kernel to time: the CPU ensemble kernel against the naive loop, or the "
                   "CUDA kernel with the observer (needs numba-cuda and a GPU); with --headline, "
                   "where the map's kernel runs")
    b.add_argument("--observe-every", type=int, default=4, metavar="N",
                   help="steps between classifier samples")
    b.add_argument("--map", type=int, metavar="N",
                   help="instead: time an N x N sweep through the whole engine vs the naive loop")
    b.add_argument("--spec", metavar="SPEC.toml",
                   help="instead: a spec's sweep end to end (this fresh process, kernels from the "
                        "disk cache) against the bare kernel on the same launches and steps (no "
                        "observer, fallback, labels or file); fixed-step methods, full-length runs")
    b.add_argument("--scaling", metavar="SPEC.toml", nargs="?", const=SCALING_HEADLINE,
                   help="instead: a spec's sweep (--scaling --headline [N]: the headline map of "
                        "N^3 launches, N = 100 when not given) in fresh processes on 1 thread, on "
                        "--threads threads and on --workers dask processes (warm caches): the "
                        "fixed cost per process (a fresh process sweeping 8 launches), per run "
                        "the wall time, the kernels' time (sweep -v) and the rest, the speed-ups "
                        "on wall and on kernel time, and whether the maps are the same")
    b.add_argument("--threads", type=int, metavar="N",
                   help="--scaling: numba threads of the one-process run (default: every core)")
    b.add_argument("--workers", type=int, metavar="N",
                   help="--scaling: dask worker processes of the last run (default: --threads)")
    b.add_argument("--headline", type=int, metavar="N", nargs="?", const=100,
                   help="instead: an N^3 period-mode map (N = 100 when not given) with label "
                        "agreement against full integration on 1000 random launches; with "
                        "--scaling, the map the scaling bench sweeps")
    b.add_argument("--method", choices=("dop853", "rk4", "quadrature"), default=None,
                   help="--headline: the map's method (dop853: rtol 1e-9, the observer on each "
                        "step; rk4: dt 2e-4 s, samples every 0.8 ms; quadrature: no time "
                        "stepping, and the dop853 map swept after it in the same run, for the "
                        "speed-up; default: dop853, rk4 with --backend cuda)")
    b.add_argument("--period", type=int, metavar="N",
                   help="instead: period mode against full integration on an N x N map, the "
                        "period-map path against simulate, and the quadrature's speed")
    b.add_argument("--T", type=float, default=20.0, metavar="SECONDS",
                   help="duration (s) for --map / --headline (also with --scaling) / --period")
    b.set_defaults(func=_cmd_bench)

    s = cmd("sweep", help="integrate and classify every launch of a spec; write a netCDF map")
    s.add_argument("spec", help="sweep spec (TOML); see the docs' 'Sweep specs' page; an "
                                "output path in it is relative to the current folder")
    s.add_argument("--resume", action="store_true",
                   help="continue an interrupted sweep of this spec from its saved parts")
    s.add_argument("--force", action="store_true",
                   help="overwrite an existing result or discard saved parts")
    s.add_argument("-o", "--output", metavar="OUT.nc",
                   help="output file (.nc), overriding the spec's [output] file")
    s.add_argument("--chunk", type=int, metavar="N",
                   help="launches per chunk, the unit of saving and of dask tasks (default: the "
                        "spec's [run] chunk: 4096, 524288 on cuda)")
    s.add_argument("--backend", choices=("cpu", "cuda"),
                   help="where the fixed-step kernel runs, overriding the spec's [run] backend "
                        "(cuda: an NVIDIA GPU through numba-cuda)")
    g = s.add_mutually_exclusive_group()
    g.add_argument("--scheduler", metavar="ADDR",
                   help="address of a running dask.distributed scheduler (tcp://host:port)")
    g.add_argument("--workers", type=int, metavar="N",
                   help="start a local dask cluster with N worker processes")
    s.add_argument("--dask-timeout", type=float, default=30.0, metavar="SECONDS",
                   help="longest wait (s) for the dask scheduler (to connect, or to come back) "
                        "and for workers when none is left")
    s.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                   help="progress bar on stderr (default: when stderr is a terminal)")
    s.add_argument("-q", "--quiet", action="count", default=0,
                   help="only errors and the path written")
    s.add_argument("-v", "--verbose", action="count", default=0,
                   help="also a line as launches finish (-vv: and this process's dask logs)")
    s.set_defaults(func=_cmd_sweep)

    p = cmd("plot", help="draw a regime map (PNG, PDF or SVG) from a sweep's netCDF file")
    p.add_argument("result", help="a ballsurvey netCDF map (.nc, written by sweep)")
    _add_drawn_axes_options(p)
    p.add_argument("--at", action="append", metavar="AXIS=VALUE",
                   help="fix another axis at one of its values (within half a grid step; "
                        "repeatable), in the axis's units (deg or rad/s)")
    p.add_argument("--facet", metavar="AXIS", help="one panel per value of AXIS")
    p.add_argument("--no-contours", action="store_true", help="omit the n_sides = 3, 4 contours")
    p.add_argument("-o", "--output", metavar="FILE",
                   help="figure file, .png, .pdf or .svg (default: RESULT with .png)")
    p.set_defaults(func=_cmd_plot)

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
    q.set_defaults(func=_cmd_path)

    e = cmd("explore", help="explore a map in the browser: hover, click a launch to see its "
                            "path (needs ballsurvey[explore])")
    e.add_argument("result", help="a ballsurvey netCDF map (.nc)")
    e.add_argument("--port", type=int, default=5006, metavar="P",
                   help="port of the local app (served on 127.0.0.1 only)")
    e.add_argument("--no-browser", action="store_true",
                   help="print the address instead of opening a browser")
    _add_drawn_axes_options(e)
    e.add_argument("--at", action="append", metavar="AXIS=VALUE",
                   help="start another axis at one of its values (repeatable), in its units "
                        "(deg or rad/s); default: its first value")
    e.add_argument("--html", metavar="OUT.html",
                   help="instead: write a self-contained static page (works offline) with hover "
                        "values and, for a slice of at most 1024 launches, each launch's path "
                        "precomputed over one theta cycle and drawn on click")
    e.add_argument("--allow-host", action="append", metavar="NAME[:PORT]",
                   help="also answer requests for this host name (repeatable; default port: "
                        "--port), for deliberate sharing behind a proxy; without it the app "
                        "answers only Host 127.0.0.1:PORT and localhost:PORT")
    e.set_defaults(func=_cmd_explore)

    an = cmd("animate", help="animate one launch: the truncated ball with its flat face and probe "
                             "from above and from the side, the path being traced (GIF or MP4)")
    _add_launch_options(an)
    an.add_argument("--T", type=float, default=3.0, metavar="SECONDS",
                    help="duration of the motion shown (s); a square or triangle of the paper "
                         "closes in 2-3 s")
    an.add_argument("--dt", type=float, default=1e-4, metavar="SECONDS", help="largest step (s)")
    an.add_argument("--fps", type=float, default=20.0,
                    help="frames per second of the file (1 to 120)")
    an.add_argument("--speed", type=float, default=0.5,
                    help="seconds of motion per second of playback (0.5: half speed, so the "
                         "quick turns near theta = 90 deg can be followed)")
    an.add_argument("--probe-m", type=float, default=0.0254, metavar="METRES",
                    help="probe length (m) on the flat face")
    _add_rolling_option(an)
    an.add_argument("-o", "--output", required=True, metavar="FILE.gif|FILE.mp4",
                    help="GIF (Pillow, always there) or MP4 (needs ffmpeg on the PATH)")
    _add_ball_options(an)
    an.set_defaults(func=_cmd_animate)

    ft = cmd("fit", help="find the launch that reproduces a measured track (CSV, Tracker's "
                         "export)")
    ft.add_argument("track", metavar="TRACK.csv",
                    help="header row (a name line above it is skipped) and columns t (s) and "
                         "x, y (m, centre of mass), or two tracked masses named tip and base, or "
                         "x_tip, y_tip, x_base, y_base (m, with --probe-m); optionally theta_deg "
                         "(deg) and chidot (rad/s); tab, comma or semicolon separated; rows with "
                         "a blank or NaN cell dropped")
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
    ft.set_defaults(func=_cmd_fit)

    r = cmd("query", help="list the launches of a map that give a shape, best first")
    r.add_argument("result", help="a ballsurvey netCDF map (.nc)")
    g = r.add_mutually_exclusive_group(required=True)
    g.add_argument("--shape", metavar="WORD",
                   help="a label word (circle, square, triangle, ngon, star, ..., or a status)")
    g.add_argument("--n-sides", type=int, metavar="N", help="polygons that close with N sides")
    r.add_argument("--format", choices=("table", "csv", "json"), default="table",
                   help="table for people; csv or json (keys without units; the units and the "
                        "values common to every row are given once) for scripts")
    lim = r.add_mutually_exclusive_group()
    lim.add_argument("--limit", type=int, default=None, metavar="N",
                     help="at most N rows (default: 20)")
    lim.add_argument("--all", action="store_true", help="every matching row")
    r.add_argument("--max-n-error", type=float, metavar="E",
                   help="only launches with |n_sides - nearest whole n| <= E")
    r.add_argument("--max-closure", type=float, metavar="METRES",
                   help="only launches whose corner drifts at most METRES (m) per circuit")
    r.set_defaults(func=_cmd_query)

    gl = cmd("gallery", help="draw sample paths behind each label of a map, integrated again, "
                             "to check the labels by eye")
    gl.add_argument("result", help="a ballsurvey netCDF map (.nc)")
    gl.add_argument("-o", "--output", metavar="FILE",
                    help="figure file, .png, .pdf or .svg (default: RESULT-gallery.png)")
    gl.add_argument("--per-label", type=int, default=4, metavar="N", help="paths per label")
    gl.add_argument("--seed", type=int, default=0, help="random seed of the sample")
    gl.add_argument("--T", type=float, metavar="SECONDS",
                    help="duration (s) of each integration (default: the map's)")
    _add_ball_options(gl, default="the map's own ball")
    gl.set_defaults(func=_cmd_gallery)

    pp = cmd("paper", help="reproduce the paper's numerical figures and compare numbers")
    pp.add_argument("-o", "--output", default="results/paper", metavar="FOLDER",
                    help="folder for the figures")
    pp.add_argument("--format", choices=("png", "pdf", "svg"), default="png",
                    help="file format of the figures")
    pp.set_defaults(func=_cmd_paper)

    fd = cmd("find", help="solve for the launch condition that closes an exact n-gon")
    g = fd.add_mutually_exclusive_group(required=True)
    g.add_argument("--shape", metavar="WORD", help="triangle or square (other polygons: --n-sides)")
    g.add_argument("--n-sides", type=int, metavar="N",
                   help="number of sides of the polygon (3 to 1000)")
    fd.add_argument("--theta0-deg", type=float, metavar="DEG", help="initial tilt (deg)")
    fd.add_argument("--thetadot0", type=float, default=0.0, metavar="RATE",
                    help="initial tilt rate (rad/s)")
    fd.add_argument("--chidot0", type=float, metavar="RATE", help="initial precession rate (rad/s)")
    fd.add_argument("--phidot0", type=float, metavar="RATE", help="initial spin rate (rad/s)")
    fd.add_argument("--solve", default="chidot0", choices=("chidot0", "theta0_deg", "phidot0"),
                    help="the launch variable to solve for")
    fd.add_argument("--bracket", type=float, nargs=2, metavar=("LO", "HI"),
                    help="search range of the solved variable (its units: deg or rad/s)")
    fd.add_argument("--trace-theta0", type=float, nargs=3, metavar=("START", "STOP", "NUM"),
                    help="trace the curve of exact n-gons in the (theta0, chidot0) plane: NUM "
                         "values of theta0 from START to STOP (deg)")
    fd.add_argument("-o", "--output", metavar="FILE.csv", help="CSV file for --trace-theta0")
    _add_ball_options(fd)
    fd.set_defaults(func=_cmd_find)

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
    rf.set_defaults(func=_cmd_refine)

    ac = cmd("accuracy", help="work-precision report: error against run time, RK4 and adaptive, "
                              "paper and extreme cases")
    ac.add_argument("-o", "--output", default="results/accuracy", metavar="FOLDER",
                    help="folder for the .nc file and the figure")
    ac.add_argument("--format", choices=("png", "pdf", "svg"), default="png",
                    help="file format of the figure")
    ac.add_argument("--quick", action="store_true", help="fewer cases and settings (a minute)")
    ac.add_argument("--ensemble", type=int, nargs="?", const=256, default=None, metavar="N",
                    help="only the ensemble table: N launches around the square (256 when not "
                         "given), final position error against launches/s for DOP853 (SIMD "
                         "lanes), dopri5 and RK4")
    ac.set_defaults(func=_cmd_accuracy)
    # `ballsurvey --help` lists the commands in the order people use them, not of the code above
    rank = {name: i for i, name in enumerate(COMMAND_ORDER)}
    sub._choices_actions.sort(key=lambda a: rank.get(a.dest, len(rank)))
    return ap


@contextmanager
def _compiling_line(command: str):
    """While a command runs, its first numba compilation prints one line on stderr, so a cold
    start (seconds to a minute) is not silent; `sweep` says it itself, with its progress."""
    if command == "sweep":
        yield
        return
    from .sweep.compute import compile_watch

    def say(msg):
        print(f"ballsurvey {command}: {msg}", file=sys.stderr, flush=True)

    with compile_watch(say):
        yield


def _quiet_unraisable(info) -> None:
    """sys.unraisablehook for the command line: a Ctrl-C that lands inside a callback Python
    cannot raise from (a garbage-collection callback of distributed's, a finaliser) is dropped
    without its 'Exception ignored in ...' traceback: the run's own Ctrl-C handling says what
    happened, in one line. Anything else is reported as usual."""
    if issubclass(info.exc_type, KeyboardInterrupt):
        return
    sys.__unraisablehook__(info)


def main(argv=None) -> int:
    """Run the command in `argv` (default: sys.argv[1:]); returns the exit status."""
    code = _main(argv)
    _skip_final_collection()
    return code


def _skip_final_collection() -> None:
    """The command line (`ballsurvey._COMMAND_LINE`) only, its command done: the objects alive
    now are left out of the interpreter's garbage collections at exit (`gc.freeze`). Those
    collections walk every object of numba, xarray and pandas, about 0.25 s of each process's
    exit; Python does not promise to finalize objects still alive at exit anyway, and the
    command's files are closed by then (exit handlers still run). `main` called from Python
    leaves the caller's collector alone."""
    import gc

    if getattr(sys.modules.get("ballsurvey"), "_COMMAND_LINE", False):
        gc.freeze()


def _main(argv=None) -> int:
    sys.unraisablehook = _quiet_unraisable
    try:
        parser = build_parser()
        args, extra = parser.parse_known_args(argv)
        if extra:  # said by the command's own parser, so the line names the command
            parser.commands[args.command].error(f"unrecognized arguments: {' '.join(extra)}")
    except SystemExit as exc:  # --help, --version (0) or an option argparse refused (2)
        return exc.code
    from .limits import RunError

    try:
        with _compiling_line(args.command):
            args.func(args)
    except InputError as exc:
        print(f"ballsurvey {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except RunError as exc:
        print(f"ballsurvey {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except BrokenPipeError:  # the reader of stdout left (`query ... | head`): nothing to say
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as exc:  # the system refused a file operation (disk full, permissions)
        name = exc.filename or getattr(args, "html", None) or getattr(args, "output", None)
        what = f"{exc.strerror or exc}: {name}" if name else str(exc)
        print(f"ballsurvey {args.command}: error: {what or type(exc).__name__}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        _ignore_more_ctrl_c()
        print(f"ballsurvey {args.command}: interrupted", file=sys.stderr)
        return 130
    _ignore_more_ctrl_c()  # done: a Ctrl-C while the interpreter shuts down changes nothing
    return 0


def _ignore_more_ctrl_c() -> None:
    """After the one line of an interruption, or the work: a burst of Ctrl-C (a key held down)
    does not cut the exit short into a traceback or a death by signal. The command line only
    (`ballsurvey._COMMAND_LINE`): `main` called from Python leaves the caller's Ctrl-C alone."""
    import signal
    import threading

    command_line = getattr(sys.modules.get("ballsurvey"), "_COMMAND_LINE", False)
    if command_line and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
