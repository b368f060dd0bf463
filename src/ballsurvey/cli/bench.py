"""`ballsurvey bench`: timings of the kernels, a spec's sweep, scaling, the headline map."""
from __future__ import annotations

from ..limits import InputError
from .options import UserError, _check_cuda, _opt

#: what `bench --scaling` holds when given without a spec (then --headline names the map)
SCALING_HEADLINE = "(the headline map)"


def _check_bench(args):
    """Every bench option by the shared rules, before anything is compiled or timed."""
    from .. import limits

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


def run(args):
    from ..bench import run_bench, run_map_bench

    _check_bench(args)
    if args.scaling is None and (args.threads is not None or args.workers is not None):
        raise InputError("--threads and --workers go with --scaling SPEC.toml or --scaling "
                         "--headline [N]")

    if args.map is not None:
        run_map_bench(n=args.map, T=args.T, dt=args.dt)
        return
    if args.spec:
        from ..bench import run_spec_bench

        run_spec_bench(args.spec)
        return
    if args.scaling is not None:
        from ..bench import run_scaling

        headline = args.scaling == SCALING_HEADLINE
        run_scaling(None if headline else args.scaling, threads=args.threads,
                    workers=args.workers, headline=args.headline if headline else None,
                    T=args.T, method=args.method or "dop853")
        return
    if args.period is not None:
        from ..bench import run_period_bench

        run_period_bench(n=args.period, T=args.T)
        return
    if args.headline is not None:
        from ..bench import run_headline

        method = args.method or ("rk4" if args.backend == "cuda" else "dop853")
        if args.backend == "cuda":
            from ..compose import CUDA_METHODS

            if method not in CUDA_METHODS:
                raise InputError(f"--headline --backend cuda runs rk4 or quadrature, not {method}")
            _check_cuda()
        run_headline(n=args.headline, T=args.T, method=method, backend=args.backend)
        return
    if args.backend == "cuda":
        from ..bench import run_bench_cuda

        _check_cuda()
        run_bench_cuda(n_launches=args.launches, n_steps=args.steps, dt=args.dt,
                       repeats=args.repeats, observe_every=args.observe_every)
        return
    run_bench(n_launches=args.launches, n_steps=args.steps, dt=args.dt, repeats=args.repeats,
              block=args.block, observe_every=args.observe_every)


def add_parser(cmd):
    """`ballsurvey bench`'s parser, made by `cmd` (`build_parser`'s)."""
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
    return b
