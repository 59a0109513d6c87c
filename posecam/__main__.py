"""`python -m posecam` and the `posecam` script."""

from posecam._start import guard_start


def main() -> None:
    guard_start()   # until posecam.cli.main installs its own handlers
    from posecam.cli import end, main as posecam

    try:
        posecam()
    except SystemExit as exc:
        end(exc.code)


if __name__ == "__main__":
    main()
