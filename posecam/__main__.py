"""`python -m posecam` and the `posecam` script.

A Ctrl-C or SIGTERM while the command's modules are still being imported ends it with one line
(nothing to clean up yet); `posecam.cli.main` installs the handlers it keeps when it runs.
"""

import os
import signal
import threading


def _interrupted_while_starting(signum, frame) -> None:
    os.write(2, b"posecam: interrupted\n" if signum == signal.SIGINT else b"posecam: terminated\n")
    os._exit(130 if signum == signal.SIGINT else 143)


def main() -> None:
    if threading.current_thread() is threading.main_thread():
        for signum in (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, _interrupted_while_starting)
    from posecam.cli import main as posecam

    posecam()


if __name__ == "__main__":
    main()
