import sys

from .cli import main

try:
    sys.exit(main())
finally:
    # under `python -m`, CPython ends the process by SIGINT, whatever its exit status, once a
    # Ctrl-C has left an `exec` of a string (scipy's import runs one as numba starts), even a
    # Ctrl-C caught since; running a string to its end clears that, so the status stays 130
    exec("pass")
