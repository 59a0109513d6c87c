"""Ctrl-C or SIGTERM while `posecam` is starting: one line and the documented code, no traceback.

Installed by `posecam.__main__` first thing (importing the package installs nothing);
`posecam.cli.main` replaces it with the handlers it keeps when the command runs. It imports
nothing but `os` and `signal`, so that the window before it is set stays as short as it can be.
"""

import os
import signal


def _interrupted_while_starting(signum, frame) -> None:
    os.write(2, b"posecam: interrupted\n" if signum == signal.SIGINT else b"posecam: terminated\n")
    os._exit(130 if signum == signal.SIGINT else 143)


def guard_start() -> None:
    for signum in (signal.SIGINT, signal.SIGTERM):
        try:
            signal.signal(signum, _interrupted_while_starting)
        except ValueError:   # not the main thread: whoever runs us keeps their handlers
            return
