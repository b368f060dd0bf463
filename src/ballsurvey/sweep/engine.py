"""Run a sweep: plan, compute, save parts, assemble the CF netCDF file. This module orchestrates;
each concern has its own module:

* `plan`: the chunk plan (each chunk a rectangular hyperslab of the grid and a contiguous range of
  launches, so one write) and the launch table;
* `compute`: integrating a chunk as a sequence of units of work (progress within a chunk, Ctrl-C
  within about a second, bit-identical results whatever the chunking);
* `parts`: the output's lock, the parts folder (a verified part per finished chunk, a partial part
  per chunk interrupted by Ctrl-C) and resuming;
* `executors`: in this process, or on a dask.distributed cluster (and starting one);
* `provenance`: the global attributes; `ballsurvey.store.write_netcdf`: the file itself.

In this process, a chunk's part is saved by a background thread while the next chunk is
computed (one part in flight, so parts are saved in chunk order; Ctrl-C and errors wait for it).
The netCDF file grows in a private temporary folder as the parts are saved (`_GrowingMap`); when
all chunks are done, the chunks of an earlier run are added from their parts one at a time
(memory bounded by the chunk size), and the file is read back, checked and renamed into place;
only then are the parts removed. A run that stops drops the growing file (its parts are what is
kept), and one whose file cannot be written assembles it from the parts at the end.
"""
from __future__ import annotations

import os
import shutil
import signal
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from .. import limits
from ..classify.labels import LABELS
from ..limits import RunError
from ..store import MapWriter, netcdf_lock
from ..store import write_netcdf as _write_netcdf_store
from .compute import ChunkInterrupted, compile_watch, compute_chunk, fields_of, n_launches
from .executors import DASK_WAIT_S, dask_client, run_dask, run_embedded
from .parts import (
    OutputBusy,
    OutputLock,
    OutputRefused,
    OutputUnwritable,
    PartInvalid,
    UpToDate,
    _notice,
    _part_path,
    _write_part,
    check_output_path,
    lock_path,
    output_is_current,
    parts_dir,
    prepare_output,
    read_part,
    read_partials,
    remove_partial,
    write_partial,
)
from .plan import launch_table, plan_chunks
from .provenance import global_attrs
from .spec import Spec

__all__ = ["run_sweep", "SweepInterrupted", "assemble", "verify_output", "plan_chunks",
           "launch_table", "compute_chunk", "OutputLock", "OutputBusy", "OutputRefused",
           "OutputUnwritable", "UpToDate", "lock_path", "parts_dir", "output_is_current",
           "check_output_path", "read_part", "prepare_output", "dask_client", "DASK_WAIT_S"]


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C: every finished unit of work is saved in `parts`; `kept` of `total` launches."""

    def __init__(self, parts: Path, kept: int, total: int):
        super().__init__(f"interrupted; {kept} of {total} launches are saved in {parts}")
        self.parts, self.kept, self.total = parts, kept, total


def _write_netcdf(path: Path, spec: Spec, chunks: list, command: str, get_part,
                  writer: MapWriter | None = None) -> None:
    """Write the netCDF file from the parts, one chunk in memory at a time (writer: the file
    open already, holding the chunks it wrote; closed here)."""
    attrs = global_attrs(spec, command) if writer is None else {}
    _write_netcdf_store(path, spec, chunks, attrs, get_part, writer)


class _GrowingMap:
    """The map file filled while the run computes: opened in a private temporary folder beside
    the output when the run starts, each chunk's slab written as its part is saved (by the part
    writer, in the background), so that what is left when the last chunk is done is the chunks
    of an earlier run, the check and the rename (`assemble`). Written this way, the headline
    map's file no longer takes 0.3 s of one core after the kernels: its compression runs
    beside them. A file that cannot be opened or written is dropped (`writer` None), and the
    map is then assembled from the parts at the end, as a resumed run's is."""

    def __init__(self, spec: Spec, chunks: list, command: str):
        out = spec.output
        self.tmpdir, self.writer = None, None
        try:
            self.tmpdir = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-", dir=out.parent))
            self.writer = MapWriter(self.tmpdir / out.name, spec, chunks,
                                    global_attrs(spec, command))
        except (OSError, RuntimeError):
            self.discard()
        except BaseException:  # Ctrl-C while the file is made: no folder left behind
            self.discard()
            raise

    def put(self, k: int, result: dict) -> bool:
        """Chunk k's slab written; False where the file is (now) dropped."""
        if self.writer is None:
            return False
        try:
            self.writer.put(k, result)
            return True
        except (OSError, RuntimeError, ValueError):
            self.discard()
            return False

    def discard(self) -> None:
        """Close and remove the file and its folder; again: nothing."""
        writer, self.writer = self.writer, None
        if writer is not None:
            try:
                writer.close()
            except (OSError, RuntimeError):
                pass
        if self.tmpdir is not None:
            shutil.rmtree(self.tmpdir, ignore_errors=True)


#: most labels `verify_output` reads back at once (int8: 16 MB): reads of a few chunks each cost
#: more in netCDF4's own handling than in reading
VERIFY_READ = 1 << 24
#: the parts a run saves are kept in memory for its assembly up to this many bytes in all (more
#: are read back from their files): reading back the parts of a 1e6-launch map (9 MB: label and
#: n_sides) cost 0.2 s. A part is verified against its checksum when a resumed run reads it.
HELD_PARTS_BYTES = 64 << 20


def verify_output(path: Path, spec: Spec) -> None:
    """Raise RunError unless `path` is this spec's complete map (digest, shape, every label: each
    value as stored, a word's code)."""
    import netCDF4

    try:
        with netcdf_lock(direct=True), netCDF4.Dataset(path) as nc:
            ok = getattr(nc, "spec_digest", None) == spec.digest
            lab = nc.variables["label"]
            lab.set_auto_mask(False)  # the values as stored (plain arrays, quicker)
            ok = ok and tuple(lab.shape) == tuple(spec.shape)
            for _lo, _hi, slab in (plan_chunks(spec.shape, max(spec.chunk, VERIFY_READ))
                                   if ok else []):
                v = np.asarray(lab[slab])
                if v.size and not ((v >= 0) & (v < len(LABELS))).all():
                    ok = False
                    break
    except (OSError, KeyError, RuntimeError) as exc:
        raise RunError(f"the written map {path} cannot be read back ({exc}); finished chunks are "
                       "kept: run again with --resume") from None
    if not ok:
        raise RunError(f"the written map {path} does not hold this spec's results; finished "
                       "chunks are kept: run again with --resume")


#: a write that failed with less than this free on the output's device is said to have met a
#: full disk (netCDF4 and HDF5 report it in their own words)
DISK_FULL_BYTES = 1 << 20


def _free_bytes(folder: Path) -> int | None:
    """Bytes free to this user on folder's device; None where that cannot be read."""
    try:
        return shutil.disk_usage(folder).free
    except OSError:
        return None


def assemble(spec: Spec, parts: Path, chunks: list, command: str, get_part=None,
             growing: _GrowingMap | None = None) -> Path:
    """Write the netCDF file from the part files into a private temporary folder beside the
    output, verify it, and rename it into place. growing: the file filled while the run
    computed (its chunks are not written again), finished here."""
    out = spec.output
    if get_part is None:
        def get_part(k):
            return read_part(parts, k, spec, chunks[k][0], chunks[k][1])
    writer = growing.writer if growing is not None else None
    if writer is not None:
        tmpdir = growing.tmpdir
    else:
        tmpdir = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-", dir=out.parent))
    try:
        tmp = tmpdir / out.name
        try:
            _write_netcdf(tmp, spec, chunks, command, get_part, writer=writer)
        except (OSError, RuntimeError) as exc:
            if isinstance(exc, RunError):
                raise
            why = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
            free = _free_bytes(tmpdir)  # before the half-written file is removed
            when = ""
            if free is not None and free < DISK_FULL_BYTES:
                # netCDF4 and HDF5 name a full disk "HDF error" or even "Permission denied"
                why = f"no space left on the device ({free // 1024} kB free; {why})"
                when = " once there is room"
            raise RunError(f"cannot write {out}: {why}; finished chunks are kept in {parts}: "
                           f"run again with --resume{when}") from None
        verify_output(tmp, spec)
        os.replace(tmp, out)
    finally:
        if growing is not None:
            growing.discard()
        shutil.rmtree(tmpdir, ignore_errors=True)
    verify_output(out, spec)
    return out


# ---------------------------------------------------------------------------------------------
# running
def _make_parent_dirs(out: Path) -> list:
    """Create the output's missing parent folders; returns them (to remove if refused)."""
    created = []
    d = out.parent
    missing = []
    while not d.exists() and d != d.parent:
        if d.name == "..":  # mkdir of a/.. would say "File exists"
            raise OutputUnwritable(f"cannot write the output {out}: the folder {d.parent} does "
                                   "not exist (the path steps out of it with '..')")
        missing.append(d)
        d = d.parent
    try:
        for d in reversed(missing):
            d.mkdir()
            created.append(d)
    except OSError as exc:
        _remove_dirs(created)
        raise OutputUnwritable(f"cannot write the output {out}: {exc.strerror}") from None
    return created


class _NoSigint:
    """Ignore Ctrl-C while saving what an interrupted run finished (main thread only)."""

    def __enter__(self):
        self.old = None
        if threading.current_thread() is threading.main_thread():
            self.old = signal.signal(signal.SIGINT, signal.SIG_IGN)
        return self

    def __exit__(self, *exc):
        if self.old is not None:
            signal.signal(signal.SIGINT, self.old)


class _DeferSigint:
    """Hold a Ctrl-C back while a part is written and counted (main thread only), then hand it
    to the handler that was there: a part cut short is not on disk, but its launches were
    counted as kept. An ignored SIGINT (while an interrupted run saves, or in a background job)
    stays ignored; a Ctrl-C during a write that fails is still delivered."""

    def __enter__(self):
        self.old, self.hit = None, False
        if threading.current_thread() is threading.main_thread():
            old = signal.getsignal(signal.SIGINT)
            if old is not signal.SIG_IGN and old is not None:
                self.old = signal.signal(signal.SIGINT, self._hold)
        return self

    def _hold(self, signum, frame):
        self.hit = True

    def __exit__(self, *exc):
        if self.old is None:
            return
        signal.signal(signal.SIGINT, self.old)
        if self.hit:
            if callable(self.old):  # Python's (raises KeyboardInterrupt) or the caller's own
                self.old(signal.SIGINT, None)
            else:  # SIG_DFL: what it would have done, as Python reports it
                raise KeyboardInterrupt


class _PartWriter:
    """Saves chunks' parts in a background thread while the next chunks are computed (the
    kernels release the GIL, and a part's labels, checksum, file and fsync then cost no wall
    time): one batch of parts (the chunks of one call) in flight at a time, saved in order, so
    parts are written in the order the chunks finish.

    save(k, result) writes part k (raising RunError when it cannot); `settle` waits for the
    batch in flight and raises what a save raised; `close` waits for it and drops its failure
    (for a run that is already ending on another exception: what is kept is what `save`
    recorded as saved)."""

    def __init__(self, save):
        from concurrent.futures import ThreadPoolExecutor

        self.save = save
        self.pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="ballsurvey-part")
        self.pending = None  # ([k, ...], future)

    def _save_all(self, items) -> None:
        for k, result in items:
            self.save(k, result)

    def submit(self, items: list) -> None:
        """Save [(k, result), ...] in the background, in that order."""
        # a Ctrl-C between the hand-over and `pending` would leave parts in flight that
        # `settle` does not wait for: it is held until `pending` is set
        with _DeferSigint():
            self.pending = ([k for k, _ in items], self.pool.submit(self._save_all, items))

    def failed(self) -> bool:
        """The batch in flight is done and a save raised."""
        return (self.pending is not None and self.pending[1].done()
                and self.pending[1].exception() is not None)

    def settle(self) -> list:
        """Wait for the batch in flight (a Ctrl-C meanwhile is held until it is on disk, then
        raised); returns its chunks ([] when none was in flight)."""
        if self.pending is None:
            return []
        ks, future = self.pending
        with _DeferSigint():
            future.exception()  # waits
        self.pending = None
        future.result()  # its failure, if any
        return ks

    def close(self) -> None:
        self.pending = None
        self.pool.shutdown(wait=True)


def run_sweep(spec: Spec, *, resume: bool = False, force: bool = False, client=None,
              progress: bool | None = None, command: str = "", on_chunk=None, notice=None,
              dask_wait_s: float = DASK_WAIT_S, on_unit=None, report: dict | None = None,
              parallel: bool | None = None) -> Path:
    """Run (or continue) a sweep and write its netCDF file. `client`: a dask.distributed Client.

    progress: a progress bar on stderr (default: when stderr is a terminal); on_unit(done, total):
    called as launches finish (within chunks when run in this process); on_chunk(k): after chunk
    k is saved; notice(line): what the run has to say (compiling, parts computed again); report:
    a dict filled with 'wall_s', 'compile_s', 'computed' (launches computed by this run) and
    'resumed' (launches taken from an earlier run); on dask also `run_dask`'s account of the
    workers' time. parallel: in this process, run the parallel kernels (numba threads) or the
    serial ones; None: as `executors.parallel_for` decides (serial for a small map).

    One writer per output: the run holds `<output>.lock` for its whole life; a second run on the
    same output is refused (OutputBusy). On resume the recorded chunk plan is used and parts are
    verified (those that fail are computed again). In this process each part is saved in the
    background while the next chunk runs, in chunk order; on_chunk(k) is called from this
    thread once part k is on disk (after the next chunk is computed). Parts are removed only
    once the final file is in place and verified. Ctrl-C saves every finished unit of work and
    raises SweepInterrupted."""
    from tqdm import tqdm

    t_start = time.perf_counter()
    notice = notice or _notice
    out = Path(spec.output)
    check_output_path(out)
    limits.chunk_plan(spec.shape, spec.chunk)
    created = _make_parent_dirs(out)
    lock = OutputLock(out)
    try:
        lock.acquire()
    except BaseException:
        _remove_dirs(created)
        raise
    started = False
    growing = None  # the map file filled as the run goes (`_GrowingMap`)
    try:
        spec, parts, done = prepare_output(spec, resume=resume, force=force, notice=notice)
        started = True
        chunks = plan_chunks(spec.shape, spec.chunk)
        partials = read_partials(parts, spec, chunks, done, notice)
        todo = [k for k in range(len(chunks)) if k not in done]
        n_resumed = sum(chunks[k][1] - chunks[k][0] for k in done) + \
            sum(n_launches(p) for p in partials.values())
        state = {"done": n_resumed}
        if progress is None:
            progress = sys.stderr.isatty()
        bar = tqdm(total=spec.n_launches, initial=n_resumed, unit="launch", disable=not progress,
                   desc=spec.title[:40], smoothing=0.1, file=sys.stderr, dynamic_ncols=True)

        def say(msg):
            if progress:
                bar.clear()
            notice(msg)
            if progress:
                bar.refresh()

        def advance(n):
            state["done"] += n
            bar.update(n)
            if on_unit is not None:
                on_unit(state["done"], spec.n_launches)

        saved = set(done)  # chunks whose part is on disk
        on_disk = {k: n_launches(p) for k, p in partials.items()}  # partial parts' launches

        def kept():
            """Launches on disk: whole parts, and partial parts of chunks with none. Counted
            from what was saved, not from what was computed: a Ctrl-C that no handler holds (a
            second one while the first ends the run) loses the launches of the call in hand."""
            return sum(chunks[k][1] - chunks[k][0] for k in saved) + \
                sum(n for k, n in on_disk.items() if k not in saved)

        held: dict = {}  # parts this run saved, kept for the assembly (`HELD_PARTS_BYTES`)
        held_bytes = 0
        if todo:
            growing = _GrowingMap(spec, chunks, command)

        def save(k, result):
            nonlocal held_bytes
            lo, hi, _ = chunks[k]
            result = fields_of(result)  # labelled here: in the writer's thread, in the background
            with _DeferSigint():
                try:
                    _write_part(parts, k, lo, hi, spec.digest, result)
                except OSError as exc:  # a full disk, a folder gone read-only
                    raise RunError(f"cannot save {_part_path(parts, k)}: "
                                   f"{exc.strerror or exc}; {kept()} of {spec.n_launches} "
                                   f"launches are kept in {parts}: run again with --resume "
                                   "once it can be written") from None
                remove_partial(parts, k)
                saved.add(k)
            if growing is not None and growing.put(k, result):
                return  # in the file already: nothing to hold for the assembly
            size = sum(np.asarray(v).nbytes for v in result.values())
            with _DeferSigint():
                if held_bytes + size <= HELD_PARTS_BYTES:
                    held[k] = result
                    held_bytes += size

        def finished(k, result):
            save(k, result)
            if on_chunk is not None:
                on_chunk(k)

        # in this process: each part is saved in the background while the next chunk runs
        writer = _PartWriter(save) if client is None else None

        def settle():
            """Wait for the parts in flight, then tell on_chunk they are saved."""
            for j in writer.settle():
                if on_chunk is not None:
                    on_chunk(j)

        def finished_behind(items):
            """Chunks [(k, result), ...] are computed: once the parts before them are on disk,
            save them in the background. A Ctrl-C while waiting saves them too (a
            ChunkInterrupted of the last whole chunk, the others its prefixes); an interruption
            raised by on_chunk leaves them unsaved."""
            try:
                before = writer.settle()
            except KeyboardInterrupt:
                *rest, (k, result) = items
                whole = ChunkInterrupted(result, n_launches(result))
                whole.chunk, whole.prefixes = k, dict(rest)
                raise whole from None
            for j in before:
                if on_chunk is not None:
                    on_chunk(j)
            writer.submit(items)

        def advance_and_check(n):
            advance(n)
            if writer.failed():  # a part could not be saved: stop now, not after this chunk
                writer.settle()

        compile_s = 0.0
        try:
            with compile_watch(say) as compiling:
                if client is None:
                    run_embedded(spec, chunks, todo, finished_behind, partials=partials,
                                 on_unit=advance_and_check, unlabelled=True, parallel=parallel)
                    settle()
                else:
                    run_dask(client, spec, chunks, todo, finished, dask_wait_s,
                             partials=partials, on_task=advance, report=report)
            compile_s = compiling["seconds"]
        except (KeyboardInterrupt, RunError) as exc:
            bar.close()
            with _NoSigint():
                if writer is not None:  # the parts in flight first: parts stay in order
                    writer.close()
                if growing is not None:  # the run ends here: no file to fill
                    growing.discard()
                if isinstance(exc, ChunkInterrupted) and exc.done > 0:
                    k = exc.chunk
                    lo, hi, _ = chunks[k]
                    try:
                        if exc.done >= hi - lo:
                            _write_part(parts, k, lo, hi, spec.digest, fields_of(exc.result))
                            saved.add(k)
                            remove_partial(parts, k)
                        else:
                            write_partial(parts, k, lo, hi, spec.digest, fields_of(exc.result),
                                          exc.done)
                            on_disk[k] = exc.done
                    except OSError:  # not saved: not counted as kept
                        pass
                # the whole chunks computed with the one cut short (in this process), or
                # (dask) each unsaved chunk's launches back in a row from its start
                prefixes = getattr(exc, "prefixes", {})
                for k, result in list(prefixes.items()):
                    lo, hi, _ = chunks[k]
                    n = n_launches(result)
                    try:
                        if n >= hi - lo:  # whole (Ctrl-C came while it was being saved)
                            finished(k, result)
                        else:
                            write_partial(parts, k, lo, hi, spec.digest, result, n)
                            on_disk[k] = n
                    except (OSError, RunError):  # not saved: not counted as kept
                        pass
            if isinstance(exc, RunError):
                raise
            raise SweepInterrupted(parts, kept(), spec.n_launches) from None
        finally:
            bar.close()
            if writer is not None:
                with _NoSigint():
                    writer.close()

        def get_part(k):
            if k in held:
                return held.pop(k)
            lo, hi, _ = chunks[k]
            try:
                return read_part(parts, k, spec, lo, hi)
            except PartInvalid as exc:
                notice(f"{_part_path(parts, k)} failed verification ({exc}); computing it again")
                result = compute_chunk(spec.text, spec.source, lo, hi, parallel=True)
                _write_part(parts, k, lo, hi, spec.digest, result)
                return read_part(parts, k, spec, lo, hi)

        try:
            out = assemble(spec, parts, chunks, command, get_part, growing)
        except KeyboardInterrupt:  # every chunk is saved: only the assembly is left to do
            raise SweepInterrupted(parts, spec.n_launches, spec.n_launches) from None
        with _NoSigint():
            shutil.rmtree(parts)
        if report is not None:
            report.update(wall_s=time.perf_counter() - t_start, compile_s=compile_s,
                          computed=spec.n_launches - n_resumed, resumed=n_resumed)
        return out
    finally:
        if growing is not None:
            growing.discard()
        lock.release()
        if not started:
            _remove_dirs(created)


def _remove_dirs(created: list) -> None:
    for d in reversed(created):
        try:
            d.rmdir()
        except OSError:
            pass
