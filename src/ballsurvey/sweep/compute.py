"""Computing launches: a chunk is integrated as a sequence of smaller units of work.

A launch's result never depends on which launches share its batch (the kernels are bit-identical
for any block size, thread count or batch; tested), so a chunk can be cut into units run one
after the other without changing a bit of the map. Units give the progress bar something to move
within a chunk, bound how long Ctrl-C waits (Python sees the signal only between kernel calls),
and are what an interrupted run keeps. Their size adapts so that each takes about `UNIT_S`.

`compute_chunk` is a pure function of (spec text, launch range): the embedded run (numba threads)
and a dask worker (one serial, GIL-free kernel) call it on the same chunks.
"""
from __future__ import annotations

import math
import threading
import time
from contextlib import contextmanager, nullcontext

import numpy as np

from ..compose import survey_fields, survey_run
from .plan import launch_table
from .spec import Spec, load_spec

#: target wall time of one unit of work (s): Ctrl-C acts within about this
UNIT_S = 0.5
#: one parallel kernel call at a time in this process: sweeps run from several threads take
#: turns (each call fills every core anyway), and numba's fallback threading layer
#: ("workqueue", where neither OpenMP nor TBB is found) aborts the process on concurrent calls
PARALLEL_LOCK = threading.Lock()


class ChunkInterrupted(KeyboardInterrupt):
    """Ctrl-C inside a chunk: `result` holds the launches finished before it ({variable: array},
    the first `done` launches of the chunk)."""

    def __init__(self, result: dict, done: int):
        super().__init__()
        self.result = result
        self.done = done


class Unlabelled:
    """A chunk's launches integrated, labelled when `fields_of` asks (the embedded run's part
    writer does, in its thread, while the next chunk is integrated: the labelling is numpy on
    one core, and the kernels release the GIL). pieces: results ({variable: array}) and
    `compose.SurveyRun`s, in launch order."""

    def __init__(self, pieces: list, variables):
        self.pieces, self.variables = pieces, tuple(variables)

    @property
    def n(self) -> int:
        """How many launches it holds."""
        return sum(n_launches(p) if isinstance(p, dict) else len(p.res.outcome)
                   for p in self.pieces)

    def fields(self) -> dict:
        """The labelled results; the observer records are let go once labelled (only the
        fields are kept, however long the object is held)."""
        out = concat([p if isinstance(p, dict) else _labelled(p, self.variables)
                      for p in self.pieces], self.variables) if self.pieces else {}
        self.pieces = [out] if out else []
        return out


class Share:
    """Launches a..b of a result computed for several chunks at once (an `Unlabelled` or
    {variable: array}): `fields_of` labels the whole result on its first call (one labelling
    for all the chunks) and copies this share out of it."""

    def __init__(self, whole, a: int, b: int):
        self.whole, self.a, self.b = whole, int(a), int(b)

    @property
    def n(self) -> int:
        return self.b - self.a

    def fields(self) -> dict:
        return {k: np.array(v[self.a:self.b]) for k, v in fields_of(self.whole).items()}


def fields_of(result) -> dict:
    """{variable: array} of a result, labelling an `Unlabelled` one (or a `Share` of one)."""
    return result.fields() if isinstance(result, (Unlabelled, Share)) else result


def _labelled(run, variables) -> dict:
    """{variable: array} of a `compose.SurveyRun`, labelled."""
    f = survey_fields(run, variables)
    return {k: np.asarray(f[k]) for k in variables}


def compute_launches(spec: Spec, lo: int, hi: int, parallel: bool = True,
                     block: int | None = None, *, label: bool = True):
    """Integrate and label launches lo..hi-1 of a spec in one kernel call; {variable: 1-D array}
    (label False: the `compose.SurveyRun`, for `Unlabelled`)."""
    with PARALLEL_LOCK if parallel else nullcontext():
        run = survey_run(launch_table(spec, lo, hi), T=spec.T, dt=spec.dt, method=spec.method,
                         rtol=spec.rtol, atol=spec.atol, block=block or spec.block,
                         observe_every=spec.observe_every,
                         cycles=spec.cycles if spec.mode == "period" else 0,
                         thresholds=spec.thresholds, parallel=parallel, backend=spec.backend)
    return _labelled(run, spec.variables) if label else run


def _threads(parallel: bool) -> int:
    if not parallel:
        return 1
    import numba

    return max(1, numba.get_num_threads())


#: launches a SIMD vector of the kernels holds (8 doubles of AVX-512; a multiple of AVX2's 4): a
#: block of another size runs its remainder one launch at a time, each launch at about
#: SCALAR_SHARE of a whole vector's time (600 square-map launches on two threads took 1.11 s in
#: blocks of 38 against 0.83 s in blocks of 64: (32 + 48 s) / 40 = 1.34)
SIMD_LAUNCHES = 8
SCALAR_SHARE = 0.45


def busiest_thread(n: int, threads: int, block: int) -> float:
    """The time, in SIMD vectors (`SCALAR_SHARE` a launch of a block's remainder), of the
    busiest thread when n launches in blocks of `block` are shared out as numba shares a
    parallel loop's iterations: an equal, contiguous range of blocks a thread."""
    sizes = [min(block, n - lo) for lo in range(0, n, block)]
    share = math.ceil(len(sizes) / threads)
    return max(sum(b // SIMD_LAUNCHES + SCALAR_SHARE * (b % SIMD_LAUNCHES)
                   for b in sizes[t * share:(t + 1) * share]) for t in range(threads))


def _balanced_block(n: int, threads: int, largest: int) -> int:
    """The block size for a unit of n launches on `threads` threads: at most `largest`, as few
    blocks a thread as that allows, of the sizes that share them out evenly (in whole SIMD
    vectors or not) or take n / threads, the one whose busiest thread is done first
    (`busiest_thread`). 141 launches on two threads in blocks of 64 leave one thread two blocks
    against the other's 13 launches; in blocks of 40 the threads have 80 and 61. Results never
    depend on the block size."""
    per = math.ceil(n / threads)  # launches a thread
    size = min(largest, math.ceil(per / math.ceil(per / largest)))
    whole = min(largest, SIMD_LAUNCHES * math.ceil(size / SIMD_LAUNCHES))
    # the shortest of: an even share, whole vectors, and blocks of n / threads or the largest
    return min((min(largest, per), size, whole), key=lambda b: busiest_thread(n, threads, b))


def n_launches(result) -> int:
    """How many launches a result ({variable: array}, or `Unlabelled`) holds."""
    if isinstance(result, (Unlabelled, Share)):
        return result.n
    return len(next(iter(result.values())))


def concat(pieces: list[dict], variables) -> dict:
    if len(pieces) == 1:
        return pieces[0]
    return {k: np.concatenate([p[k] for p in pieces]) for k in variables}


def compute_chunk(spec_text: str, spec_source: str, lo: int, hi: int, parallel: bool = True, *,
                  done: dict | None = None, on_unit=None, unit: int | None = None,
                  unit_s: float = UNIT_S, spec: Spec | None = None,
                  pace: dict | None = None, unlabelled: bool = False):
    """Integrate and label launches lo..hi-1 of a spec as units run in sequence; {variable: array}.

    done: results of the chunk's first launches (from an interrupted run), not computed again.
    on_unit(n): called after each unit with its number of launches. unit: a fixed unit size
    (default: adaptive, about unit_s seconds each). Ctrl-C raises ChunkInterrupted with the
    launches finished so far. On the GPU (backend cuda) the chunk is one unit: a kernel launch
    needs many launches to fill the card, and lasts as long as its slowest launch.
    spec: the spec `spec_text` parses to, when the caller has it (not parsed again per chunk).
    pace: a dict shared by the chunks of one run: the adaptive unit size carries over from one
    chunk to the next (key 'size') instead of starting small in each (a map of many small
    chunks would otherwise spend its time on units of a few launches); key 'target' holds the
    launches that take about unit_s at the pace measured (`executors.run_embedded` computes that
    many launches of successive chunks in one call). The units never change
    a launch's result. unlabelled: return an `Unlabelled` (labelled later by `fields_of`, the
    same numbers); a Ctrl-C then raises ChunkInterrupted with an `Unlabelled` too."""
    if spec is None:
        spec = load_spec(spec_source, text=spec_text)
    pace = {} if pace is None else pace
    pieces = [done] if done else []
    a = lo + (n_launches(done) if done else 0)
    threads = _threads(parallel)
    smallest = min(hi - lo, 4 * threads)
    quantum = spec.block * threads
    if spec.backend == "cuda":
        unit = hi - lo
    size = unit or max(smallest, pace.get("size", 0))
    try:
        while a < hi:
            b = min(hi, a + size)
            t0 = time.perf_counter()
            block = _balanced_block(b - a, threads, spec.block)
            pieces.append(compute_launches(spec, a, b, parallel, block,
                                           label=not unlabelled))
            took = time.perf_counter() - t0
            if on_unit is not None:
                on_unit(b - a)
            if unit is None:  # aim at unit_s per unit; grow at most 4x at a time
                target = max(smallest, (b - a) / max(took, 1e-6) * unit_s)
                pace["target"] = int(target)
                # a unit cut short by the chunk's end may shrink the size, not grow it
                size = int(min(4 * (b - a) if b - a == size else size, target))
                # whole blocks, as many for each thread (numba gives each an equal share of
                # the blocks, in order): 140 launches in blocks of 64 would leave one of two
                # threads a block to do alone, a third of the unit's time with the other idle
                # (and blocks cut smaller to balance them lose the kernel's SIMD width)
                if size > quantum:
                    size -= size % quantum
                pace["size"] = size
            a = b
    except KeyboardInterrupt:
        # what is saved is what was computed: a Ctrl-C between a unit's end and `a = b` must not
        # drop that unit (it was already counted as done). Unlabelled, the units stay so: the
        # caller labels them where a second Ctrl-C cannot cut that short (and lose them)
        got = Unlabelled(pieces, spec.variables)
        if not unlabelled:
            got = got.fields()
        raise ChunkInterrupted(got, n_launches(got) if got else 0) from None
    if unlabelled:
        return Unlabelled(pieces, spec.variables)
    return concat(pieces, spec.variables)


@contextmanager
def compile_watch(notice):
    """While active, the first numba compilation calls notice(...) once; yields a dict whose
    'seconds' is the time spent compiling."""
    from numba.core import event

    state = {"seconds": 0.0, "depth": 0, "t0": 0.0, "told": False}

    class _Listener(event.Listener):
        def on_start(self, ev):
            if state["depth"] == 0:
                state["t0"] = time.perf_counter()
                if not state["told"]:
                    state["told"] = True
                    notice("compiling numba kernels (a few seconds, up to a minute after an "
                           "install or an edit of the physics)")
            state["depth"] += 1

        def on_end(self, ev):
            state["depth"] -= 1
            if state["depth"] == 0:
                state["seconds"] += time.perf_counter() - state["t0"]

    with event.install_listener("numba:compile", _Listener()):
        yield state
