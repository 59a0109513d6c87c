"""A video's frames decoded ahead in a thread of their own: the same frames, in order, at most a
few ahead, errors raised in the reader's caller, the thread gone once the caller stops."""

import threading
import time

import cv2
import numpy as np
import pytest

from posecam.errors import InputError
from posecam.io.media import READ_AHEAD, open_media, read_ahead


def _readers() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name == "posecam-decode"]


def _wait_gone(timeout: float = 2.0) -> bool:
    end = time.monotonic() + timeout
    while _readers() and time.monotonic() < end:
        time.sleep(0.02)
    return not _readers()


def test_read_ahead_frames_are_the_decoded_frames(tmp_path):
    path = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 25, (64, 48))
    rng = np.random.default_rng(0)
    for _ in range(12):
        writer.write(rng.integers(0, 255, (48, 64, 3), dtype=np.uint8))
    writer.release()
    media = open_media(path)
    cap = cv2.VideoCapture(str(path))
    plain = []
    while (read := cap.read())[0]:
        plain.append(cv2.cvtColor(read[1], cv2.COLOR_BGR2RGB))
    got = list(media.frames())
    assert [i for i, _, _ in got] == list(range(12))
    assert all(np.array_equal(a, b) for (_, _, a), b in zip(got, plain, strict=True))
    assert _wait_gone()


def test_read_ahead_waits_for_its_caller():
    made = []

    def items():
        for i in range(100):
            made.append(i)
            yield i

    ahead = read_ahead(items())
    assert next(ahead) == 0
    time.sleep(0.3)
    assert len(made) <= READ_AHEAD + 2   # the one held, the queue's, the one waiting to be put
    ahead.close()
    assert _wait_gone()
    assert len(made) < 100


def test_read_ahead_raises_what_the_reader_raised():
    def items():
        yield 1
        raise InputError("frame 2 is damaged")

    ahead = read_ahead(items())
    assert next(ahead) == 1
    with pytest.raises(InputError, match="frame 2 is damaged"):
        next(ahead)
    assert _wait_gone()


def test_an_abandoned_read_closes_its_source():
    closed = threading.Event()

    def items():
        try:
            while True:
                yield np.zeros(3)
        finally:
            closed.set()

    ahead = read_ahead(items())
    next(ahead)
    del ahead   # the caller stops (an exception, Ctrl-C, a break)
    assert closed.wait(2.0)
    assert _wait_gone()
