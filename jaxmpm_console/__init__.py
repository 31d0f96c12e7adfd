"""The ``jaxmpm`` console script's launcher: Ctrl-C is answered from the process's first moment.

Importing ``jaxmpm`` (and JAX with it) takes seconds. The launcher is a package of its own, so that
the console script installs its SIGINT handler before that import starts: a Ctrl-C during it ends the
process with one line, ``jaxmpm: interrupted``, and status 130, as one during a run does.
"""

import os
import signal
import threading


def interrupted(signum, frame) -> None:
    """The SIGINT handler while ``jaxmpm`` is imported: nothing is computed or saved yet, so the
    process leaves at once, with one line and status 130."""
    os.write(2, b"jaxmpm: interrupted\n")
    os._exit(130)


def console() -> None:
    """The ``jaxmpm`` console script: install the quiet Ctrl-C handler, import the command line and
    run it (``jaxmpm.cli.console``)."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, interrupted)
    from jaxmpm.cli import console as run

    run()
