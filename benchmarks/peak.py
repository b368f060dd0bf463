"""Run a command; print its exit status, wall time and peak memory (the largest RSS among the
processes it waited for): python benchmarks/peak.py COMMAND [ARGS...]"""
import resource
import subprocess
import sys
import time

t = time.perf_counter()
rc = subprocess.call(sys.argv[1:])
wall = time.perf_counter() - t
mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
print(f"[{' '.join(sys.argv[1:])}] exit {rc}, wall {wall:.1f} s, peak memory {mb:.0f} MB")
sys.exit(rc)
