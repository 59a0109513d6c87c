"""Frame sources: a still image, a video file, or a folder of images, read one frame at a time.

A folder is one of two things (`folder_kind`):
- a **sequence** (the frames of one video): every image has the same size, every name is one
  prefix followed by a frame number (`frame_0001.png`, `img7.jpg`, ..., ordered by that
  number) and the images carry no camera EXIF (frames cut from a video have none); it is one
  input with one size, one set of intrinsics and a frame rate of `DEFAULT_FPS` (30 fps).
- **photos**: anything else (sizes differ, names are not numbered frames, or a camera's EXIF,
  as in a phone's IMG_0001.JPG, IMG_0002.JPG, ...). Each photo is an input of its own, with
  its own size, intrinsics and EXIF (`expand_inputs`).

Part of a video or sequence (`FrameSelection`: `--start/--end/--stride`, in frames or seconds)
is read by seeking to the first frame and grabbing, not decoding, the frames skipped between
two kept ones; the kept frames keep their index and time in the source.

A **live source** is a camera index (`0`, `1`: a number that is not a file here) or a stream
URL that OpenCV's FFmpeg opens (`rtsp://`, `http://`, `udp://`, ...; `is_stream`). It has no
frame count: it is read until it ends, `--end`, or the caller stops asking for frames; times
are frame index / the stream's declared rate. Opening and each read give up after
STREAM_TIMEOUT_MS.

Only regular files and folders are opened (a FIFO or a device would block forever), and
OpenCV never sees a file name: images are decoded from their bytes, videos whose names
OpenCV cannot take (not UTF-8) are opened through a temporary link with an ASCII name.

posecam reports damaged inputs itself, in one line: the `posecam` command turns FFmpeg's own
messages off (OpenCV's `OPENCV_FFMPEG_LOGLEVEL`, posecam.cli.ENVIRONMENT); libjpeg, which has
no such switch, is muted while an image is decoded.
"""

from __future__ import annotations

import os
import queue
import re
import stat
import struct
import sys
import tempfile
import threading
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from posecam.errors import InputError, warn
from posecam.io.validate import MAX_PIXELS
from posecam.results import DEFAULT_FPS

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff", ".webp")   # read as still images
VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv")   # videos posecam writes, and looks for in a take folder
READ_AHEAD = 2      # video frames decoded ahead of the one being posed (a thread of their own)
TIME_ROUNDING = 5e-5  # s: half the last decimal of a pose file's times (4 decimals)


def exact_times(indices, times, fps: float | None) -> np.ndarray:
    """Frame times as the frame rate gives them, index / rate, where every time is that to
    within the rounding of a pose file's times (TIME_ROUNDING): a constant-rate input read
    back, or timed by its container to the millisecond. The rate is `fps`, or `fps` times the
    step between the indices (every k-th frame kept: `fps` is the rate of the frames kept).
    Otherwise (a variable rate, no rate, missing times) the times as they are."""
    index = np.asarray(indices, dtype=float)
    t = np.asarray(times, dtype=float)
    if not fps or not len(t) or not np.isfinite(t).all():
        return t
    steps = np.diff(index)
    step = int(np.gcd.reduce(steps.astype(np.int64))) if len(steps) and (steps > 0).all() else 1
    for rate in dict.fromkeys((fps, fps * step)):
        exact = index / rate
        if np.all(np.abs(exact - t) <= TIME_ROUNDING * (1 + 1e-6)):
            return exact
    return t
_NUMBERED = re.compile(r"^(.*?)(\d+)$")
STREAM_SCHEMES = ("rtsp://", "rtsps://", "rtmp://", "http://", "https://", "udp://", "tcp://", "srt://")
STREAM_TIMEOUT_MS = 10_000
_FRAMES_OR_SECONDS = re.compile(r"^(\d+)$|^(\d+(?:\.\d*)?|\.\d+)s$")


@dataclass(frozen=True)
class FrameSelection:
    """Part of a video or frame sequence: from `start` up to, not including, `end`, every
    `stride`-th frame. Each is a frame count ("120") or seconds ("2s", "0.5s"); seconds are
    turned into frames at the input's frame rate (rounded to the nearest frame)."""

    start: str | None = None
    end: str | None = None
    stride: str | None = None

    def __post_init__(self) -> None:
        for name in ("start", "end", "stride"):
            value = getattr(self, name)
            if value is not None and not _FRAMES_OR_SECONDS.match(str(value).strip()):
                raise InputError(f"--{name} takes a frame number (120) or seconds (2s, 0.5s), got {value!r}")
        if self.stride is not None and self._frames(self.stride, 1000.0) == 0 and self._frames(self.stride, 1.0) == 0:
            raise InputError(f"--stride must be at least one frame, got {self.stride!r}")

    @staticmethod
    def _frames(value: str, fps: float) -> int:
        m = _FRAMES_OR_SECONDS.match(str(value).strip())
        return int(m.group(1)) if m.group(1) is not None else round(float(m.group(2)) * fps)

    def frames(self, fps: float, count: int) -> range:
        """The kept frame indices of an input of `count` frames at `fps`."""
        first = self._frames(self.start, fps) if self.start is not None else 0
        stop = min(self._frames(self.end, fps), count) if self.end is not None else count
        step = max(1, self._frames(self.stride, fps)) if self.stride is not None else 1
        if first >= stop:
            end = f"--end {self.end}" if self.end is not None and self._frames(self.end, fps) < count \
                else f"the end of the input ({count} frames at {fps:g} fps)"
            raise InputError(f"--start {self.start} (frame {first}) is not before {end}: no frame to read")
        return range(first, stop, step)


@dataclass
class Media:
    """An opened input: its size, frame rate and frame count (1 for an image)."""

    path: Path | str     # a live source's camera index or URL as given
    kind: str            # "image", "video", "sequence" or "stream"
    width: int
    height: int
    fps: float | None
    frame_count: int     # 0: unknown (a live source)
    image: np.ndarray | None = field(default=None, repr=False)   # a still image, decoded once
    files: list[Path] = field(default_factory=list, repr=False)  # a sequence's frames, in order
    selection: FrameSelection | None = None                      # part of a video or sequence
    stop: threading.Event | None = field(default=None, repr=False)   # once set, a live source ends

    @property
    def selected(self) -> range:
        """The indices of the frames `frames()` yields (all of them without a selection)."""
        count = self.frame_count or sys.maxsize
        return self.selection.frames(self.fps, count) if self.selection else range(count)

    @property
    def sample_fps(self) -> float | None:
        """The rate of the frames yielded: the input's, divided by the selection's stride."""
        return self.fps / self.selected.step if self.fps else self.fps

    def frames(self) -> Iterator[tuple[int, float, np.ndarray]]:
        """Yield (index, time in s, RGB uint8 image) of the selected frames, index and time
        those of the source; memory stays flat for any length. A video's frames are decoded
        ahead, in a thread of their own (`read_ahead`)."""
        if self.kind == "image":
            yield 0, 0.0, self.image if self.image is not None else read_image(self.path)
        elif self.kind == "sequence":
            for i in self.selected:
                p = self.files[i]
                rgb = read_image(p)
                if rgb.shape[:2] != (self.height, self.width):
                    raise InputError(f"{p} is {rgb.shape[1]}x{rgb.shape[0]}, the other frames of "
                                     f"{self.path} are {self.width}x{self.height}")
                yield i, i / DEFAULT_FPS, rgb
        else:
            yield from read_ahead(self._video_frames())

    def _video_frames(self) -> Iterator[tuple[int, float, np.ndarray]]:
        wanted = self.selected
        # without --end, read to the video's real end (a declared count may be off)
        stop = wanted.stop if self.selection and self.selection.end is not None else None
        index, ok = wanted.start, True
        # a file's frame times are the container's (its presentation times), so that a
        # variable-frame-rate video gets its real times; a live source's, and a file's once its
        # container gives none (or times that do not increase), are index / fps
        timed, last = self.kind != "stream", -1.0
        with _stream_capture(str(self.path)) if self.kind == "stream" else _video_capture(self.path) as cap:
            if index:
                _seek(cap, index)
            while (stop is None or index < stop) and not (self.stop is not None and self.stop.is_set()):
                ok, bgr = cap.read()
                if not ok:
                    break
                time = index / self.fps
                if timed:
                    seconds = cap.get(cv2.CAP_PROP_POS_MSEC) / 1000.0
                    if np.isfinite(seconds) and seconds >= 0 and seconds > last:
                        time = last = seconds
                    else:
                        timed = False
                        warn(f"{self.path} gives no frame times from frame {index} on; times are frame / "
                             f"{self.fps:g} fps (wrong if its frame rate varies)")
                yield index, time, cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
                index += wanted.step
                for _ in range(wanted.step - 1):   # skipped frames: grabbed, not decoded into images
                    cap.grab()
        if not ok and index < self.frame_count:
            warn(f"{self.path} ended after {index} of its {self.frame_count} declared frames "
                 "(a truncated or damaged video?)")


def read_ahead(items: Iterator, depth: int = READ_AHEAD) -> Iterator:
    """`items` (a video's frames) produced in a thread of their own, at most `depth` ahead of
    the one the caller holds: OpenCV decodes without Python's lock, so the next frame is decoded
    while this one is posed. What the thread raises is raised here; memory stays flat (at most
    `depth` frames wait), and the thread stops (and closes `items`) once the caller stops,
    ends or is interrupted (a daemon thread: Ctrl-C never waits for it)."""
    waiting: queue.Queue = queue.Queue(maxsize=depth)
    stop, done = threading.Event(), object()

    def hand(item: object) -> bool:
        while not stop.is_set():
            try:
                waiting.put(item, timeout=0.1)
                return True
            except queue.Full:
                continue
        return False

    def read() -> None:
        try:
            for item in items:
                if not hand(item):
                    return
            hand(done)
        except BaseException as exc:  # noqa: BLE001 -- raised again in the caller's thread
            hand(exc)
        finally:
            items.close()

    reader = threading.Thread(target=read, name="posecam-decode", daemon=True)
    reader.start()
    try:
        while (item := waiting.get()) is not done:
            if isinstance(item, BaseException):   # what the reader raised
                raise item
            yield item
    finally:
        stop.set()


def _seek(cap: cv2.VideoCapture, index: int) -> None:
    """Put `cap` at frame `index`: OpenCV's seek where it lands there exactly, else by grabbing."""
    if cap.set(cv2.CAP_PROP_POS_FRAMES, index) and int(cap.get(cv2.CAP_PROP_POS_FRAMES)) == index:
        return
    cap.set(cv2.CAP_PROP_POS_FRAMES, 0)
    for _ in range(index):
        if not cap.grab():
            return


@contextmanager
def _native_stderr_silenced() -> Iterator[None]:
    """Mute what libjpeg prints to the process's stderr while an image decodes; posecam reports
    a damaged image itself."""
    sys.stderr.flush()
    saved = os.dup(2)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(devnull)
        os.close(saved)


def check_input(path: str | os.PathLike, what: str = "") -> Path:
    """An existing, readable regular file or folder, or InputError (FIFOs, devices, sockets)."""
    if not os.fspath(path):
        raise InputError(f"{what or 'input'}: an empty name is not a file")
    path = Path(path)
    name = f"{what} {path}".strip()
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        raise InputError(f"{name} does not exist (no such file or folder)") from None
    except OSError as exc:
        raise InputError(f"{name} cannot be read ({exc.strerror})") from None
    if not (stat.S_ISREG(mode) or stat.S_ISDIR(mode)):
        raise InputError(f"{name} is not a regular file or folder (a pipe, device or socket)")
    if not os.access(path, os.R_OK | (os.X_OK if stat.S_ISDIR(mode) else 0)):
        raise InputError(f"{name} cannot be read (permission denied)")
    return path


def read_image(path: str | os.PathLike) -> np.ndarray:
    """RGB uint8 image (EXIF orientation applied) or InputError; refused before decoding when
    its header claims more than MAX_PIXELS (any format, under the `posecam` command, which sets
    OpenCV's own limit to it too)."""
    path = Path(path)
    check_image_size(path)   # a readable regular file, too
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"{path} cannot be read ({exc.strerror})") from None
    try:
        with _native_stderr_silenced():
            bgr = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
            damaged = bgr is None and _opencv_name(path)
            if damaged:  # imread, unlike imdecode, keeps what libjpeg decoded of a damaged file
                bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    except cv2.error as exc:
        if "CV_IO_MAX_IMAGE_PIXELS" in str(exc):
            raise InputError(f"{path} claims more pixels than posecam decodes ({MAX_PIXELS // 10**6} Mpx)") from None
        bgr = None
    if bgr is None:
        raise InputError(f"{path} is not a readable image")
    if damaged or (data[:2] == b"\xff\xd8" and data.rstrip(b"\x00")[-2:] != b"\xff\xd9"):
        warn(f"{path} is damaged or truncated (a JPEG cut short?); posecam used what could be decoded")
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)


def check_image_size(path: Path) -> tuple[int, int] | None:
    """The (width, height) an image's header claims (None if its format is not one read
    here), refused with InputError over MAX_PIXELS: known before a byte is decoded."""
    check_input(path)
    try:
        with open(path, "rb") as f:
            size = header_size(f.read(1 << 20))   # a JPEG's size may follow a long EXIF block
    except OSError as exc:
        raise InputError(f"{path} cannot be read ({exc.strerror})") from None
    if size and size[0] * size[1] > MAX_PIXELS:
        raise InputError(f"{path} claims {size[0]}x{size[1]} pixels, more than posecam decodes "
                         f"({MAX_PIXELS // 10**6} Mpx)")
    return size


def header_size(data: bytes) -> tuple[int, int] | None:
    """(width, height) from a PNG, JPEG, BMP, TIFF or WebP header without decoding; None if unknown."""
    try:
        if data[:8] == b"\x89PNG\r\n\x1a\n":
            return struct.unpack(">II", data[16:24])
        if data[:2] == b"BM":
            w, h = struct.unpack("<ii", data[18:26])
            return w, abs(h)
        if data[:2] == b"\xff\xd8":
            return _jpeg_size(data)
        if data[:4] in (b"II*\x00", b"MM\x00*"):
            return _tiff_size(data)
        if data[:4] == b"RIFF" and data[8:12] == b"WEBP":
            return _webp_size(data)
    except struct.error:
        return None
    return None


def _jpeg_size(data: bytes) -> tuple[int, int] | None:
    pos = 2
    while pos + 9 <= len(data):
        if data[pos] != 0xFF:
            return None
        marker = data[pos + 1]
        if marker == 0xFF:       # fill byte
            pos += 1
            continue
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
            h, w = struct.unpack(">HH", data[pos + 5: pos + 9])
            return w, h
        pos += 2 + struct.unpack(">H", data[pos + 2: pos + 4])[0]
    return None


def _tiff_size(data: bytes) -> tuple[int, int] | None:
    """ImageWidth (tag 256) and ImageLength (257) of the first IFD."""
    order = "<" if data[:2] == b"II" else ">"
    offset = struct.unpack(order + "I", data[4:8])[0]
    count = struct.unpack(order + "H", data[offset:offset + 2])[0]
    sides = {}
    for i in range(count):
        entry = data[offset + 2 + 12 * i: offset + 14 + 12 * i]
        tag, kind = struct.unpack(order + "HH", entry[:4])
        if tag in (256, 257):
            sides[tag] = struct.unpack(order + ("H" if kind == 3 else "I"), entry[8:10] if kind == 3 else entry[8:12])[0]
    return (sides[256], sides[257]) if len(sides) == 2 else None


def _webp_size(data: bytes) -> tuple[int, int] | None:
    chunk = data[12:16]
    if chunk == b"VP8 ":
        w, h = struct.unpack("<HH", data[26:30])
        return w & 0x3FFF, h & 0x3FFF
    if chunk == b"VP8L":
        bits = struct.unpack("<I", data[21:25])[0]
        return (bits & 0x3FFF) + 1, ((bits >> 14) & 0x3FFF) + 1
    if chunk == b"VP8X":
        return int.from_bytes(data[24:27], "little") + 1, int.from_bytes(data[27:30], "little") + 1
    return None


def image_size(path: Path) -> tuple[int, int]:
    """(width, height) of an image file, from its header when possible."""
    size = check_image_size(path)
    if size is None:
        h, w = read_image(path).shape[:2]
        size = (w, h)
    return size


@contextmanager
def _video_capture(path: Path) -> Iterator[cv2.VideoCapture]:
    """An opened cv2.VideoCapture; names OpenCV cannot take go through an ASCII-named link."""
    with ExitStack() as stack:
        name = str(path)
        if not _opencv_name(path):
            tmp = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="posecam-")))
            link = tmp / ("video" + (path.suffix if path.suffix.isascii() else ""))
            link.symlink_to(path.resolve())
            name = str(link)
        cap = cv2.VideoCapture(name)
        stack.callback(cap.release)
        yield cap


def readable_video(path: Path) -> bool:
    """True when OpenCV opens the video and decodes its first frame (a check on written files)."""
    with _video_capture(path) as cap:
        return bool(cap.isOpened() and cap.read()[0])


def _opencv_name(path: Path) -> bool:
    """True when OpenCV can take this name as it is (valid UTF-8)."""
    try:
        str(path).encode("utf-8")
        return True
    except UnicodeEncodeError:
        return False


def _image_files(folder: Path) -> list[Path]:
    """The regular image files of a folder, sorted by name."""
    try:
        entries = sorted(folder.iterdir())
    except OSError as exc:
        raise InputError(f"{folder} cannot be listed ({exc.strerror})") from None
    return [p for p in entries if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file()]


def folder_holds(folder: Path) -> str:
    """What a folder holds instead of images, for its error: "4 videos (cam01.mp4, cam02.mp4,
    cam03.mp4, ...)", "2 folders (multi, single)"; "" when it holds images, nothing of use, or
    cannot be listed."""
    try:
        entries = sorted(folder.iterdir())
    except OSError:
        return ""
    if any(p.suffix.lower() in IMAGE_SUFFIXES and p.is_file() for p in entries):
        return ""
    videos = [p.name for p in entries if p.suffix.lower() in VIDEO_SUFFIXES and p.is_file()]
    folders = [p.name for p in entries if p.is_dir()]
    for names, kind in ((videos, "video"), (folders, "folder")):
        if names:
            listed = ", ".join(names[:3]) + (", ..." if len(names) > 3 else "")
            return f"{len(names)} {kind}{'s' if len(names) > 1 else ''} ({listed})"
    return ""


def _has_exif(path: Path) -> bool:
    """True when a JPEG carries an Exif block (a camera's photo, not a frame cut from a video)."""
    with open(path, "rb") as f:
        data = f.read(1 << 16)
    return data[:2] == b"\xff\xd8" and b"Exif\x00\x00" in data


def folder_kind(folder: str | os.PathLike) -> tuple[str, list[Path]]:
    """("sequence", frames in frame order) or ("photos", files by name); see the module doc."""
    folder = Path(folder)
    files = _image_files(folder)
    if not files:
        holds = folder_holds(folder)
        raise InputError(f"{folder}: folder holds no images" + (f" but {holds}: give them as the inputs" if holds else ""))
    matches = [_NUMBERED.match(p.stem) for p in files]
    numbered = all(matches) and len({(m.group(1), p.suffix.lower()) for m, p in zip(matches, files)}) == 1
    if numbered:
        files = [p for _, p in sorted(zip((int(m.group(2)) for m in matches), files), key=lambda t: t[0])]
        if not _has_exif(files[0]) and len({image_size(p) for p in files}) == 1:
            return "sequence", files
    return "photos", files


def expand_inputs(paths: list[str | os.PathLike], strict: bool = True) -> tuple[list[Path | str], list[str]]:
    """Inputs as given, with each folder of photos replaced by its photos (see the module doc;
    live sources stay the strings they are), and what was left out: without `strict`, a
    folder's photo that cannot be read (opened as `open_media` opens it) is left out, its
    one-line reason in the second list; with `strict` (or a file given by name) it raises InputError."""
    expanded, skipped = [], []
    for p in paths:
        if is_stream(p):
            expanded.append(str(p))
            continue
        p = check_input(p)
        kind, files = folder_kind(p) if p.is_dir() else ("file", [])
        if kind != "photos":
            expanded.append(p)
            continue
        for photo in files:
            if not strict:
                try:
                    open_media(photo)
                except InputError as exc:
                    skipped.append(str(exc))
                    continue
            expanded.append(photo)
    return expanded, skipped


def _check_video_size(cap: cv2.VideoCapture, path: Path) -> None:
    """Refuse, before its first frame is decoded, a video whose frames claim over MAX_PIXELS."""
    w, h = cap.get(cv2.CAP_PROP_FRAME_WIDTH), cap.get(cv2.CAP_PROP_FRAME_HEIGHT)
    if w * h > MAX_PIXELS:
        raise InputError(f"{path} claims {w:.0f}x{h:.0f} pixels per frame, more than posecam decodes "
                         f"({MAX_PIXELS // 10**6} Mpx)")


def open_media(path: str | os.PathLike, selection: FrameSelection | None = None) -> Media:
    """Open an image, a video or a folder of frames (only the `selection` of a video or
    folder); raise InputError if it cannot be read, or a still image comes with a selection."""
    media = _open_stream(str(path)) if is_stream(path) else _open(path)
    if selection is None or selection == FrameSelection():
        return media
    if media.kind == "image":
        raise InputError(f"--start, --end and --stride pick frames of a video or sequence; {path} is an image")
    media.selection = selection
    media.selected   # noqa: B018 -- a start past the end is refused now, before any work
    return media


def _open(path: str | os.PathLike) -> Media:
    path = check_input(path)
    if path.is_dir():
        kind, files = folder_kind(path)
        if kind == "photos":
            raise InputError(f"{path} holds photos, not the frames of one video (their sizes differ or "
                             "their names are not numbered frames); give each photo as an input")
        w, h = image_size(files[0])
        return Media(path, "sequence", w, h, DEFAULT_FPS, len(files), files=files)
    if path.suffix.lower() == ".json":
        raise InputError(f"{path} is a pose file, not an image or a video: `posecam fuse` reads pose files")
    if path.suffix.lower() in IMAGE_SUFFIXES:
        image = read_image(path)
        h, w = image.shape[:2]
        return Media(path, "image", w, h, None, 1, image)
    with _video_capture(path) as cap:
        _check_video_size(cap, path)
        ok, frame = cap.read() if cap.isOpened() else (False, None)
        fps = cap.get(cv2.CAP_PROP_FPS)
        count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
    if not ok:
        raise InputError(f"{path} is neither a readable image nor a readable video")
    h, w = frame.shape[:2]
    return Media(path, "video", w, h, fps if fps and fps > 0 else DEFAULT_FPS, max(count, 1))


def is_stream(source: str | os.PathLike) -> bool:
    """True for a live source: a stream URL, or a camera index that is not a file or folder here."""
    if not isinstance(source, str):
        return False
    return source.lower().startswith(STREAM_SCHEMES) or (source.isdigit() and not os.path.exists(source))


@contextmanager
def _stream_capture(source: str) -> Iterator[cv2.VideoCapture]:
    """An opened capture of a camera index or a stream URL (FFmpeg, with open and read timeouts)."""
    if source.isdigit():
        cap = cv2.VideoCapture(int(source))
    else:
        cap = cv2.VideoCapture(source, cv2.CAP_FFMPEG, [cv2.CAP_PROP_OPEN_TIMEOUT_MSEC, STREAM_TIMEOUT_MS,
                                                        cv2.CAP_PROP_READ_TIMEOUT_MSEC, STREAM_TIMEOUT_MS])
    try:
        yield cap
    finally:
        cap.release()


def _open_stream(source: str) -> Media:
    with _stream_capture(source) as cap:
        ok, frame = cap.read() if cap.isOpened() else (False, None)
        fps = cap.get(cv2.CAP_PROP_FPS)
    if not ok:
        if source.isdigit():
            raise InputError(f"camera {source} cannot be opened (no such camera here, or it gives no frame)")
        raise InputError(f"stream {source} cannot be opened (OpenCV's FFmpeg got no frame from it within "
                         f"{STREAM_TIMEOUT_MS // 1000} s)")
    h, w = frame.shape[:2]
    return Media(source, "stream", w, h, fps if 0 < fps < 1000 else DEFAULT_FPS, 0)
