"""Executors: who computes the chunks. `run_embedded` runs them in this process (numba threads,
units of work in sequence with progress); `run_dask` sends the chunks to a dask.distributed
cluster in tasks of a part of a chunk each, several per worker thread (one serial, GIL-free kernel
per worker thread), and saves a chunk once all its tasks are back; `dask_client` connects to a
running scheduler or starts a local cluster. Both call `compute_chunk` on ranges of the same
launches, and every launch's arithmetic is its own, so they give identical files."""
from __future__ import annotations

import logging
import time
from contextlib import contextmanager

from ..compose import TIMES, prefetch_fallback, stop_prefetch, warm_up
from ..integrate.tableaus import FIXED_STEP
from ..limits import RunError
from .compute import ChunkInterrupted, Share, compute_chunk, concat, n_launches
from .provenance import code_digest
from .spec import Spec

#: what a script that starts local workers without a main guard is told
UNGUARDED_HINT = ("in a script, run a sweep with workers from under "
                  "`if __name__ == \"__main__\":` (worker processes import the script again)")
UNGUARDED = f"ballsurvey: a dask worker process is importing the script: {UNGUARDED_HINT}"
#: default bounded wait (s) for a dask scheduler or for workers to (re)appear
DASK_WAIT_S = 30.0
#: dask tasks per worker thread over the launches to do (so that no thread idles at the end
#: while another finishes a long task), and the fewest launches a task holds
TASKS_PER_THREAD = 4
MIN_TASK_LAUNCHES = 64
#: a map of fewer launch-steps than this (launches x T / dt) runs on the calling thread, with
#: the serial kernel: it computes in under a second there, less than the first compilation of
#: the parallel driver costs (a few seconds); the results are the same either way
SERIAL_WORK = 1e7
#: the most launches of successive chunks the embedded run computes in one call (about 40 MB
#: of observer records; at 1.5 ms a call for the launch table, labelling and hand-over, a
#: call of 65536 launches spends about 1 % of its time on them)
GROUP_LAUNCHES = 1 << 16
#: how often (s) a wait for a task's result looks at the cluster's health
POLL_S = 1.0


def task_ranges(chunks: list, todo: list, threads: int, start: dict | None = None) -> dict:
    """{chunk k: [(a, b), ...]}: chunks `todo` cut into ranges of launches, about
    TASKS_PER_THREAD per thread of the cluster in all, none below MIN_TASK_LAUNCHES (unless what
    is left of its chunk is smaller). A one-chunk map (the default chunk holds 4096 launches) thus
    still spreads over every worker. start: {k: launches of chunk k already done (a partial part
    of an interrupted run)}; its ranges begin after them."""
    start = start or {}
    first = {k: chunks[k][0] + start.get(k, 0) for k in todo}
    n = sum(chunks[k][1] - first[k] for k in todo)
    size = max(MIN_TASK_LAUNCHES, -(-n // (TASKS_PER_THREAD * max(1, threads))))
    out = {}
    for k in todo:
        lo, hi = first[k], chunks[k][1]
        # as many tasks as size asks (rounded up, for balance), none below the fewest
        cuts = max(1, min(-(-(hi - lo) // size), (hi - lo) // MIN_TASK_LAUNCHES))
        edges = [lo + (hi - lo) * j // cuts for j in range(cuts + 1)]
        out[k] = list(zip(edges[:-1], edges[1:]))
    return out


def parallel_for(spec: Spec) -> bool:
    """Whether a map is run with the parallel kernels (numba threads): all but small maps
    (`SERIAL_WORK`) on the CPU."""
    return spec.backend != "cpu" or spec.n_launches * spec.T / spec.dt >= SERIAL_WORK


def _group(chunks: list, todo: list, i: int, partials: dict, target: int) -> list:
    """The chunks computed in one call from todo[i] on: todo[i], then those after it in a row
    (each beginning where the last ends, with no partial part) while the launches stay within
    target (at least the first chunk)."""
    group = [todo[i]]
    lo = chunks[todo[i]][0]
    for k in todo[i + 1:]:
        # a chunk done already in between ends the row: k then begins after its end
        if k in partials or chunks[k][0] != chunks[group[-1]][1] or chunks[k][1] - lo > target:
            break
        group.append(k)
    return group


def _shares(result, group: list, chunks: list, n: int) -> dict:
    """{chunk: its launches} of a result holding the first n launches of a group of chunks
    (one chunk: the result itself); a chunk only partly within them is its own key too."""
    if len(group) == 1:
        return {group[0]: result}
    lo = chunks[group[0]][0]
    return {k: Share(result, chunks[k][0] - lo, min(n, chunks[k][1] - lo))
            for k in group if chunks[k][0] - lo < n}


def _split_interrupt(exc: ChunkInterrupted, group: list, chunks: list) -> ChunkInterrupted:
    """A Ctrl-C within a group of chunks as the engine saves it: the chunk cut short (or the
    last whole one) as the interruption's `chunk` and result, the whole chunks before it as
    its `prefixes` ({chunk: launches})."""
    if len(group) == 1 or not exc.done:
        exc.chunk = group[0]
        return exc
    shares = _shares(exc.result, group, chunks, exc.done)
    k = max(shares)
    result = shares.pop(k)
    out = ChunkInterrupted(result, n_launches(result))
    out.chunk, out.prefixes = k, shares
    return out


def run_embedded(spec: Spec, chunks: list, todo: list, finished, *, partials=None,
                 on_unit=None, unlabelled: bool = False, parallel: bool | None = None) -> None:
    """Chunks `todo` in this process, in order; finished([(k, result), ...]) after each call.
    With the parallel kernels, successive chunks are computed in one call, as many as make a
    unit of work at the pace measured (`compute.UNIT_S`): a map of many small chunks (a grid's
    rows) would otherwise spend a sixth of its time on each call's launch tables, labelling
    and hand-over.
    partials: {k: results of chunk k's first launches} kept from an interrupted run.
    unlabelled: hand `finished` results that `compute.fields_of` labels (an `Unlabelled`, or a
    `Share` of one), in finished's time: a background writer's, while the next call runs.
    parallel: the parallel kernels or the serial ones; None: `parallel_for(spec)`.
    Ctrl-C raises compute.ChunkInterrupted (with its `chunk`, and the whole chunks of its call
    as `prefixes`) holding the finished launches."""
    partials = partials or {}
    pace = {}  # the unit size, carried from call to call
    parallel = parallel_for(spec) if parallel is None else parallel
    if spec.method in FIXED_STEP and spec.backend == "cpu" and todo:
        prefetch_fallback()  # compiled beside the fixed-step kernel where not cached
    try:
        i = 0
        while i < len(todo):
            # the serial kernel runs small maps only (`SERIAL_WORK`): chunk by chunk there
            target = min(pace.get("target", 0), GROUP_LAUNCHES) if parallel else 0
            group = _group(chunks, todo, i, partials, target)
            lo, hi = chunks[group[0]][0], chunks[group[-1]][1]
            try:
                result = compute_chunk(spec.text, spec.source, lo, hi, parallel=parallel,
                                       done=partials.get(group[0]), on_unit=on_unit, spec=spec,
                                       pace=pace, unlabelled=unlabelled)
            except ChunkInterrupted as exc:
                raise _split_interrupt(exc, group, chunks) from None
            except KeyboardInterrupt as exc:
                exc.chunk = group[0]
                raise
            finished(list(_shares(result, group, chunks, hi - lo).items()))
            i += len(group)
    finally:
        stop_prefetch()


def _warm_worker() -> str:
    """On a dask worker: one numba thread (workers are single-threaded), kernels compiled once,
    the worker's kernel times (`compose.TIMES`) from zero; returns the digest of the worker's
    code (`provenance.code_digest`)."""
    import numba

    from . import provenance

    numba.set_num_threads(1)
    warm_up()
    TIMES.clear()
    return provenance.code_digest()


def _chunk_task(spec_text: str, spec_source: str, lo: int, hi: int) -> tuple:
    """A dask task: `compute_chunk` on launches lo..hi-1 (serial, one unit); returns (results,
    the worker's address, its kernel times so far by phase (s, `compose.TIMES`, counted from
    `_warm_worker`)). The times ride on the results: no call to the cluster after the run, which
    a lost scheduler would hold for as long as the client waits to reconnect."""
    from distributed import get_worker

    result = compute_chunk(spec_text, spec_source, lo, hi, False, unit=hi - lo)
    return result, get_worker().address, dict(TIMES)


def run_dask(client, spec: Spec, chunks: list, todo: list, finished, wait_s: float, *,
             partials=None, on_task=None, report: dict | None = None) -> None:
    """Chunks on a dask cluster, in tasks of `task_ranges`; on_task(n) as each task's n launches
    come back (progress), finished(k, result) once all of chunk k's tasks are back. partials:
    {k: results of chunk k's first launches} kept from an interrupted run (not computed again).
    A scheduler lost, or no worker, for longer than wait_s ends the run with RunError (finished
    chunks are saved as they come). On Ctrl-C or RunError the exception carries `prefixes`:
    {k: results of chunk k's first launches, its partial and the tasks back in a row from it},
    for the caller to save as partial parts. report: a dict given a finished run's
    'workers_start_s' (the workers' first call: imports, kernels loaded), 'n_workers' (those
    warmed) and 'worker_times' ({phase: kernel seconds summed over the workers}, as
    `compose.TIMES`, from `_chunk_task`'s results)."""
    from concurrent.futures import CancelledError

    from distributed import as_completed
    from distributed.comm.core import CommClosedError
    from distributed.scheduler import KilledWorker

    partials = {k: v for k, v in (partials or {}).items() if k in todo}
    lost = (CancelledError, CommClosedError, KilledWorker, OSError, TimeoutError)
    resume_hint = "finished chunks are kept: run again with --resume"
    try:
        t_warm = time.perf_counter()
        codes = client.run(_warm_worker)
        t_warm = time.perf_counter() - t_warm
        other = {w: c for w, c in codes.items() if c != code_digest()}
        if other:
            w, c = next(iter(other.items()))
            raise RunError(f"the dask worker {w} runs other ballsurvey code (code {str(c)[:12]};"
                           f" this is code {code_digest()[:12]}): its launches could differ; "
                           f"install the same ballsurvey on every worker ({resume_hint})")
        ranges = task_ranges(chunks, todo, sum(client.nthreads().values()),
                             {k: n_launches(v) for k, v in partials.items()})
        futs = {client.submit(_chunk_task, spec.text, spec.source, a, b, pure=False): (k, a)
                for k in todo for a, b in ranges[k]}
    except lost as exc:
        raise RunError(f"the dask cluster failed ({type(exc).__name__}); {resume_hint}") from None
    back = {k: {} for k in todo}  # chunk -> {first launch of a task: its results}
    worker_times: dict = {}  # worker -> its kernel times by phase, the latest seen (they grow)

    def in_a_row(k) -> list:
        """Chunk k's results from its start on: its partial, then its tasks back in a row."""
        pieces = [partials[k]] if k in partials else []
        for a, _ in ranges[k]:
            if a not in back[k]:
                break
            pieces.append(back[k][a])
        return pieces

    def prefixes() -> dict:
        out = {}
        for k in back:
            pieces = in_a_row(k)
            if len(pieces) > (k in partials):  # something beyond the partial already saved
                out[k] = concat(pieces, spec.variables)
        return out

    def cluster_check(since):
        """None while the cluster has a scheduler and workers; else when it was first seen
        without (since, or now); RunError once that is longer ago than wait_s."""
        try:
            healthy = client.status == "running" and len(client.nthreads()) > 0
        except lost:
            healthy = False
        if healthy:
            return None
        if since is None:
            return time.monotonic()
        if time.monotonic() - since > wait_s:
            what = "no dask workers" if client.status == "running" else "lost the dask scheduler"
            err = RunError(f"{what} for {wait_s:g} s; {resume_hint}")
            err.prefixes = prefixes()
            raise err
        return since

    def result_of(fut):
        """A finished task's result. If its worker died before the result was fetched, dask
        computes the task again: wait for that as for any task, within the same bounded wait
        (without workers, fut.result() alone waits for ever)."""
        since = None
        while True:
            try:
                return fut.result(timeout=POLL_S)
            except TimeoutError:
                since = cluster_check(since)

    ac = as_completed(list(futs))
    since = None  # when the cluster was first seen without a scheduler or workers
    try:
        while not ac.is_empty():
            batch = ac.next_batch(block=False)
            for fut in batch:
                k, a = futs.pop(fut)
                back[k][a], worker, times = result_of(fut)
                seen = worker_times.setdefault(worker, {})
                for phase, t in times.items():
                    seen[phase] = max(seen.get(phase, 0.0), t)
                fut.release()  # the result is here: the worker need not keep it
                n = n_launches(back[k][a])
                if len(back[k]) == len(ranges[k]):  # the chunk is whole: save it first
                    finished(k, concat(in_a_row(k), spec.variables))
                    del back[k]
                if on_task is not None:
                    on_task(n)
            if batch:
                since = None
                continue
            time.sleep(0.1)
            since = cluster_check(since)
    except lost as exc:
        err = RunError(f"the dask cluster failed ({type(exc).__name__}: {str(exc)[:80]}); "
                       f"{resume_hint}")
        err.prefixes = prefixes()
        raise err from None
    except KeyboardInterrupt as exc:
        exc.prefixes = prefixes()
        raise
    finally:
        for fut in futs:
            fut.release()
    if report is not None:
        total: dict = {}
        for times in worker_times.values():
            for phase, t in times.items():
                total[phase] = total.get(phase, 0.0) + t
        report.update(workers_start_s=t_warm, n_workers=len(codes), worker_times=total)


def raise_log_levels(level: int, tops=("distributed", "tornado", "asyncio")) -> None:
    """Every logger of the packages `tops` at `level` at least (distributed's config sets some
    of its loggers one by one, so each is set, not only the package's own)."""
    for name in list(logging.root.manager.loggerDict) + list(tops):
        if name.split(".")[0] in tops:
            logger = logging.getLogger(name)
            logger.setLevel(max(level, logger.level))


def _distributed_log_level() -> int:
    """The level below which the local cluster's processes keep distributed's logs to
    themselves: ERROR, or higher where this process silenced distributed (the CLI does, but
    for -vv)."""
    return max(logging.ERROR, logging.getLogger("distributed").getEffectiveLevel())


def _local_worker_plugin(log_level: int = logging.ERROR):
    """A dask worker plugin for the workers of a local cluster (started for this run, closed
    with it), those started later included: SIGINT ignored (set up in the worker's main thread);
    distributed's and tornado's loggers in the worker at `log_level` (a worker whose heartbeat
    meets a scheduler closing after a Ctrl-C logs a traceback at ERROR, and `silence_logs`
    reaches only the nanny's logger there; what a lost worker means reaches the run as one line
    of ours); and at the worker's close, the objects alive then left out of its process's garbage
    collections at exit (`gc.freeze`): those collections walk every object of numba, xarray and
    pandas, and made closing a cluster of two workers take 0.4-0.9 s instead of 0.05-0.09 s
    (2-core, shared). A worker's results are back in this process by then."""
    from distributed.diagnostics.plugin import WorkerPlugin

    class LocalWorker(WorkerPlugin):
        name = "ballsurvey-local-worker"

        def setup(self, worker):
            import signal

            signal.signal(signal.SIGINT, signal.SIG_IGN)
            raise_log_levels(log_level, ("distributed", "tornado"))

        def teardown(self, worker):
            import gc

            gc.freeze()

    return LocalWorker()


@contextmanager
def dask_client(scheduler: str | None = None, workers: int | None = None,
                wait_s: float = DASK_WAIT_S):
    """A dask.distributed Client: to the scheduler at `scheduler`, or to a local cluster of
    `workers` single-threaded processes (closed on exit); None when neither is given."""
    if not scheduler and not workers:
        yield None
        return
    from distributed import Client

    cluster = None
    if scheduler:
        try:
            client = Client(scheduler, timeout=wait_s)
        except (OSError, TimeoutError) as exc:
            raise RunError(f"cannot reach the dask scheduler {scheduler} within {wait_s:g} s "
                           f"({type(exc).__name__})") from None
    else:
        # a Ctrl-C at the terminal reaches every process of the group: worker processes that
        # are starting (importing) would print a traceback each. They start with SIGINT
        # ignored, which they inherit; this process ignores it for those seconds too.
        with _ignoring_sigint():
            cluster, client = _local_cluster(workers)
    try:
        yield client
    finally:
        with _ignoring_sigint():  # closing is not cut short into a traceback
            client.close()
            if cluster is not None:
                cluster.close()


@contextmanager
def _ignoring_sigint():
    """SIGINT ignored in this process (and inherited so by processes started meanwhile); main
    thread only, else nothing changes."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


def _local_cluster(workers: int):
    """(cluster, client): a local cluster of `workers` single-threaded processes."""
    import multiprocessing

    from distributed import Client, LocalCluster

    if getattr(multiprocessing.current_process(), "_inheriting", False):
        # a worker process starting re-runs the script's top level: unguarded, it would
        # start a cluster of its own; it stops, and the run below says why
        raise SystemExit(UNGUARDED)
    # no dashboard, and the scheduler's small HTTP server on a free port (by default it
    # takes 8787 and warns when that is busy); the cluster's own logs only for errors, or
    # none where this process silenced distributed (see _local_worker_plugin)
    level = _distributed_log_level()
    try:
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               host="127.0.0.1", dashboard_address=None,
                               scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                               silence_logs=level)
    except Exception as exc:  # noqa: BLE001 - distributed raises many kinds; one line
        raise RunError(f"the local dask cluster of {workers} workers did not start "
                       f"({type(exc).__name__}: {str(exc)[:120]}); {UNGUARDED_HINT}") from None
    try:
        client = Client(cluster)
        # a Ctrl-C at the terminal reaches every process of the group: the workers of this
        # cluster leave it to this process, which keeps what came back and closes them (a
        # worker plugin: a worker started again after a loss ignores it too)
        client.register_plugin(_local_worker_plugin(level))
    except BaseException:
        cluster.close()
        raise
    return cluster, client
