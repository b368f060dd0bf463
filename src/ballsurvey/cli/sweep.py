"""`ballsurvey sweep`: run a spec's map, then its summary and (-v) where the time went."""
from __future__ import annotations

import argparse
import sys

from .options import _check_cuda, _ignore_more_ctrl_c, _opt, _out_file


def run(args):
    import shlex
    import time
    from dataclasses import replace

    from .. import limits
    from ..sweep import SweepInterrupted, load_spec, run_sweep
    from ..sweep.engine import UpToDate, check_output_path, dask_client
    from ..sweep.parts import existing_output, tidy_finished

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
    try:
        if not (args.scheduler or args.workers):
            # inside: a Ctrl-C while numba starts still names an earlier run's saved parts
            report["numba_start_s"] = _start_numba()
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
            from ..sweep.engine import parts_dir

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
    """`sweep -v`'s account of a run's time (s): numba's start (`compose.start_numba`), the kernels'
    phases (`compose.TIMES`: in this process, or on dask each worker's on average), the rest of
    the run, and on dask the cluster's start (or the connection to a running scheduler), the
    workers' first call and the client's (and a local cluster's) closing. `bench --scaling`
    reads it."""
    from ..compose import TIMES, in_line, phases_text

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
    from ..compose import start_numba

    return start_numba()


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

    from ..sweep.executors import raise_log_levels

    # a Ctrl-C inside one of distributed's waits leaves a coroutine unawaited: Python warns
    for module in ("tornado", "distributed", "asyncio"):
        warnings.filterwarnings("ignore", category=RuntimeWarning, module=module)
    raise_log_levels(logging.CRITICAL)


def sweep_summary(path, n_launches: int, report: dict) -> str:
    """The end of a sweep in a few lines: time, rate, counts per label, flagged and fallback
    launches, and the commands to look at the map."""
    import netCDF4
    import numpy as np

    from ..classify.labels import LABELS, SHAPES
    from ..integrate.tableaus import LANE_ADAPTIVE

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
    from ..store import netcdf_lock

    # netCDF4 itself: a sweep from the command line then never imports xarray (0.25 s)
    with netcdf_lock(direct=True), netCDF4.Dataset(path) as nc:
        nc.set_auto_mask(False)
        attrs = nc.__dict__
        codes = nc.variables["label"][...].ravel()
        # the lane methods (dop853) integrate every launch in the fixed frame: no fallback
        by_design = attrs.get("run_method") in LANE_ADAPTIVE
        fallback = redone = None
        if "formulation" in nc.variables and not by_design:
            form = nc.variables["formulation"][...]
            fallback, redone = int((form == 1).sum()), int((form == 2).sum())
        by_quadrature = attrs.get("run_method") == "quadrature"
        sparse = short = 0
        unresolved = codes == LABELS.index("unresolved")
        if "n_theta_cycles" in nc.variables:  # too short a run: raising T helps, not dt
            least = float(attrs.get("classify_min_cycles", 2))
            few = nc.variables["n_theta_cycles"][...].ravel() < least
            short = int((few & unresolved).sum())
            unresolved = unresolved & ~few
        if "samples_per_cycle" in nc.variables:
            floor = float(attrs.get("classify_min_samples_per_cycle", 20.0))
            with np.errstate(invalid="ignore"):
                sparse = int(((nc.variables["samples_per_cycle"][...].ravel() < floor)
                              & unresolved).sum())
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
    if short:
        lines.append(f"  unresolved for fewer than {least:g} complete theta cycles in T: {short}; "
                     f"raise [run] T")
    if sparse:
        lines.append(f"  unresolved for too few observer samples per theta cycle (under "
                     f"{floor:g}): {sparse}; lower [run] dt (fixed step) or rtol (dopri5, "
                     f"dop853)")
    if fallback is not None and by_quadrature:
        lines.append(f"  integrated (dop853) where the quadrature cannot go (tilt through the "
                     f"vertical, launched steady, a swing too small to resolve, not converged): "
                     f"{fallback}")
    elif fallback is not None:
        lines.append(f"  done again near the vertical: {redone} from their invariants by "
                     f"quadrature, {fallback} integrated in the fixed frame (where the quadrature "
                     f"cannot go)")
    best = next((w for w in ("square", "triangle", "ngon", "star", "circle")
                 if counts[LABELS.index(w)]), None)
    steps = [] if points else [f"ballsurvey plot {path}"]
    if best:
        steps.append(f"ballsurvey query {path} --shape {best}")
    if steps:
        lines.append("  next: " + "   |   ".join(steps))
    return "\n".join(lines)


def add_parser(cmd):
    """`ballsurvey sweep`'s parser, made by `cmd` (`build_parser`'s)."""
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
    return s
