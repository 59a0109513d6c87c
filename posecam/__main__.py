"""`python -m posecam` and the `posecam` script."""

from posecam._start import guard_start


def main() -> None:
    guard_start()   # until posecam.cli.main installs its own handlers
    from posecam.cli import main as posecam

    posecam()


if __name__ == "__main__":
    main()
