"""The ``rdea-lab`` command line: module-level click commands that parse
arguments and call one function of the application layer (`rdea_lab.api`).

Exit status: 0 done, 1 internal error, 2 bad input, 3 a run ended by the rig or
a limit (aborted), 130 interrupted. Only the CLI picks matplotlib's backend
(Agg, for commands that write figures).

The quick start is `rdea_lab`'s (one, run as a doctest).
"""

import os as _os

# One BLAS thread unless the user says otherwise: rdea-lab's arrays are long and thin
# (samples x a few parameters), where a threaded BLAS only contends for the cores;
# least squares on a busy 2-core machine ran 7x slower with it. Set before numpy loads.
_os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


def entry(argv=None):
    """The console entry point (``rdea-lab``; not named ``main``: that is the submodule). Ctrl-C and SIGTERM
    are caught from here on, before click and the commands load
    (what comes before is the interpreter's own start-up, a few tens of milliseconds)."""
    import sys

    from ..signals import Signals

    signals = Signals().install()
    try:
        from .errors import run
        from .main import cli

        # run() installs its own handlers over these (no moment without one: a restore here left a window in
        # which a signal was a traceback) and, as the whole process, blocks both signals once it is done.
        code = run(cli, argv, process=True)
    except KeyboardInterrupt as exc:  # before run() took over
        signals.hold()
        print(f"rdea-lab: interrupted ({exc})", file=sys.stderr)
        sys.exit(130)
    sys.exit(code)
