"""Ctrl-C or SIGTERM while `posecam` is starting: one line and the documented code, no traceback.

Installed by `posecam.__main__` first thing (importing the package installs nothing);
`posecam.cli.main` replaces it with the handlers it keeps when the command runs.
"""

import os
import signal
import threading


def _interrupted_while_starting(signum, frame) -> None:
    os.write(2, b"posecam: interrupted\n" if signum == signal.SIGINT else b"posecam: terminated\n")
    os._exit(130 if signum == signal.SIGINT else 143)


def guard_start() -> None:
    if threading.current_thread() is threading.main_thread():
        for signum in (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, _interrupted_while_starting)
