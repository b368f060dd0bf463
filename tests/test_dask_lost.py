"""A dask scheduler lost in the middle of a sweep: one line (RunError) after a bounded wait, the
finished chunks kept, and `--resume` (here without dask) gives the uninterrupted map."""
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time
from contextlib import contextmanager

import numpy as np
import pytest
import xarray as xr

from ballsurvey.limits import RunError
from ballsurvey.sweep import load_spec, run_sweep
from ballsurvey.sweep.engine import parts_dir

SPEC = """
title = "lost scheduler"
[launch]
theta0_deg = [-5.0, 0.0, 5.0, 10.0, 15.0, 20.0]
thetadot0 = 0.0
chidot0 = [2.3, 4.05]
phidot0 = -3.0
[run]
T = 3.0
dt = 1e-3
chunk = 1
[output]
file = "OUT"
"""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextmanager
def external_cluster(*worker_args):
    """A dask scheduler and one single-threaded worker as processes of their own (as a user's
    `--scheduler ADDR` would be), and a client to them: yields (client, scheduler, worker)."""
    distributed = pytest.importorskip("distributed")
    addr = f"tcp://127.0.0.1:{_free_port()}"
    sched = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host",
                              "127.0.0.1", "--port", addr.rsplit(":", 1)[1],
                              "--no-dashboard"], stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL)
    worker = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", addr,
                               "--nthreads", "1", "--no-dashboard", *worker_args],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        client = distributed.Client(addr, timeout=60)
        t0 = time.time()
        while not client.nthreads() and time.time() - t0 < 60:
            time.sleep(0.2)
        yield client, sched, worker
        try:
            client.close(timeout=2)
        except Exception:
            pass
    finally:
        for p in (worker, sched):
            p.kill()
            p.wait(10)


def _lost_spec(tmp_path):
    path = tmp_path / "lost.toml"
    path.write_text(SPEC.replace("OUT", str(tmp_path / "lost.nc")))
    return load_spec(path)


def test_lost_scheduler_mid_run_is_one_line_and_keeps_parts(tmp_path):
    spec = _lost_spec(tmp_path)
    parts = parts_dir(spec.output)
    with external_cluster("--nworkers", "1") as (client, sched, worker):

        def kill_once_a_part_is_saved(k):
            # from the run itself, right after its first part is on disk: the other chunks'
            # results are still on the worker (a thread watching the folder let a fast
            # machine finish all 12 launches before the kill)
            if sched.poll() is None:
                sched.kill()
                sched.wait(10)

        t0 = time.time()
        with pytest.raises(RunError, match="dask") as err:
            run_sweep(spec, client=client, dask_wait_s=3.0, command="test",
                      on_chunk=kill_once_a_part_is_saved)
        assert "\n" not in str(err.value) and "--resume" in str(err.value)
        assert time.time() - t0 < 120
        kept = list(parts.glob("chunk-*.npz"))
        assert kept and not spec.output.exists()
    got = run_sweep(spec, resume=True, command="test")  # the kept chunks, then the rest
    other = tmp_path / "ref.toml"
    other.write_text(SPEC.replace("OUT", str(tmp_path / "ref.nc")))
    ref_path = run_sweep(load_spec(other), command="test")
    with xr.open_dataset(got) as ds, xr.open_dataset(ref_path) as ref:
        for v in ref.data_vars:
            assert np.array_equal(ref[v].values, ds[v].values, equal_nan=True), v


def test_worker_lost_holding_finished_results_ends_with_one_line(tmp_path):
    """The only worker dies after its tasks finished but before their results were fetched:
    dask then computes them again, which without workers never happens. The run must end with
    one line after the bounded wait (it waited for ever in fut.result())."""
    from ballsurvey.sweep.executors import run_dask
    from ballsurvey.sweep.plan import plan_chunks

    spec = _lost_spec(tmp_path)
    chunks = plan_chunks(spec.shape, spec.chunk)
    saved = []
    with external_cluster("--no-nanny") as (client, sched, worker):

        def in_memory(dask_scheduler):
            return sum(ts.state == "memory" for ts in dask_scheduler.tasks.values())

        def finished(k, result):
            saved.append(k)
            if len(saved) > 1:
                return
            # every other task done and held by the worker, then the worker gone
            t1 = time.time()
            while client.run_on_scheduler(in_memory) < len(chunks) - 1:
                assert time.time() - t1 < 60
                time.sleep(0.05)
            worker.kill()
            worker.wait(10)
            while client.nthreads():
                assert time.time() - t1 < 60
                time.sleep(0.05)

        raised = []

        def run():
            try:
                run_dask(client, spec, chunks, list(range(len(chunks))), finished, 2.0)
            except RunError as exc:
                raised.append(exc)

        runner = threading.Thread(target=run, daemon=True)  # a hang fails, not stalls, the suite
        runner.start()
        runner.join(90)
        assert not runner.is_alive(), "run_dask still waiting 90 s after its only worker died"
        assert len(raised) == 1 and "no dask workers for 2 s" in str(raised[0])
        assert "\n" not in str(raised[0]) and saved == [saved[0]]


def test_ctrl_c_at_the_terminal_with_workers_is_one_line(tmp_path, big_spec_text):
    """Ctrl-C at a terminal signals the whole process group, the local cluster's worker
    processes too: they used to print a KeyboardInterrupt traceback each. Only our line now."""
    pytest.importorskip("distributed")
    (tmp_path / "big.toml").write_text(big_spec_text)
    cmd = [sys.executable, "-m", "ballsurvey", "sweep", "big.toml", "--workers", "2", "-v",
           "--no-progress"]
    proc = subprocess.Popen(cmd, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)  # its own group, as a terminal's
    killer = threading.Timer(300, lambda: os.killpg(proc.pid, signal.SIGKILL))
    killer.start()
    try:
        for line in proc.stderr:
            m = re.search(r"(\d+) of 2000 launches done", line)
            if m and int(m.group(1)) > 0:
                break
        os.killpg(proc.pid, signal.SIGINT)
        err = proc.stderr.read()
        proc.wait()
    finally:
        killer.cancel()
    assert proc.returncode == 130, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "interrupted;" in lines[0] and "--resume" in lines[0], err


def test_local_cluster_does_not_want_port_8787(recwarn):
    """dask's scheduler takes port 8787 for its HTTP server unless told otherwise, and warns
    when that is busy (a second sweep with --workers, a notebook's cluster). Ours takes a free
    port: no warning with 8787 held."""
    pytest.importorskip("distributed")
    from ballsurvey.sweep.executors import dask_client

    held = socket.socket()
    try:
        held.bind(("", 8787))
        held.listen()
    except OSError:
        pass  # busy already: the case this test is about
    try:
        with dask_client(workers=1) as client:
            assert sum(client.nthreads().values()) == 1
    finally:
        held.close()
    assert not [w for w in recwarn if "8787" in str(w.message)], [str(w.message) for w in recwarn]


def _worker_log_levels():
    import logging

    return {name: logging.getLogger(name).getEffectiveLevel()
            for name in ("distributed.worker", "distributed.core", "tornado.application")}


def test_local_workers_keep_distributed_quiet_as_this_process_does():
    """A worker whose heartbeat meets the scheduler closing after a Ctrl-C logs a traceback at
    ERROR from `distributed.worker` (seen on a 2-core CI machine: 29 lines after our one);
    dask's `silence_logs` reaches only the nanny's logger in the worker process. Where this
    process silenced distributed (the CLI does, but for -vv), the local workers' loggers are
    silenced too; where it did not, they keep ERROR."""
    pytest.importorskip("distributed")
    import logging

    from ballsurvey.sweep.executors import dask_client

    top = logging.getLogger("distributed")
    old = top.level
    try:
        top.setLevel(logging.CRITICAL)
        with dask_client(workers=1) as client:
            quiet = next(iter(client.run(_worker_log_levels).values()))
        top.setLevel(logging.WARNING)
        with dask_client(workers=1) as client:
            loud = next(iter(client.run(_worker_log_levels).values()))
    finally:
        top.setLevel(old)
    assert all(level >= logging.CRITICAL for level in quiet.values()), quiet
    assert all(level <= logging.ERROR for level in loud.values()), loud
