"""Outputs appear complete or not at all.

- `atomic_path(path)`: one file, written to a temporary name beside it and renamed on success.
- `OutputSet`: every output of one command, checked before the work (folder exists, not a
  folder itself, not one of the inputs), written to temporary names in a hidden staging folder
  beside each target, and renamed onto the targets together only when the whole command
  succeeded. On any error, Ctrl-C or SIGTERM (which the CLI turns into an exception) the
  staging folder is removed and no target is touched.

Temporary names are short ASCII names that keep the target's extension (writers such as
OpenCV's pick the format from it), so a 255-byte target name works and OpenCV never sees a
name it cannot encode. Every OSError while writing becomes an `OutputError` (exit code 4).
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from types import TracebackType

from posecam.errors import OutputError, PosecamError
from posecam.media import VIDEO_SUFFIXES, readable_video

_MAX_SUFFIX = 16   # longer "extensions" are not kept in temporary names


def _folder(target: Path) -> Path:
    return target.parent if str(target.parent) else Path(".")


def _suffix(target: Path) -> str:
    suffix = target.suffix
    return suffix if len(suffix) <= _MAX_SUFFIX and suffix.isascii() else ""


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _describe(exc: OSError) -> str:
    return exc.strerror or str(exc)


def same_file(a: str | os.PathLike, b: str | os.PathLike) -> bool:
    """True when two paths name one file (existing or not)."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.abspath(a) == os.path.abspath(b)


def check_output(target: str | os.PathLike, inputs: Iterable[str | os.PathLike] = ()) -> Path:
    """Refuse, before any work, an output that cannot be written or would overwrite an input."""
    target = Path(target)
    if not target.name:
        raise OutputError(f"cannot write {target}: it names a folder, not a file")
    folder = _folder(target)
    if not folder.is_dir():
        raise OutputError(f"cannot write {target}: folder {folder} does not exist")
    if target.is_dir():
        raise OutputError(f"cannot write {target}: it is an existing folder")
    if target.exists() and not target.is_file():
        raise OutputError(f"cannot write {target}: it exists and is not a regular file")
    if not os.access(folder, os.W_OK):
        raise OutputError(f"cannot write {target}: folder {folder} is not writable")
    for source in inputs:
        if source is not None and same_file(target, source):
            raise OutputError(f"refusing to overwrite the input {source} with an output")
    return target


@contextmanager
def atomic_path(path: str | os.PathLike, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path in the target's folder; rename it onto `path` on success.

    On any error, including Ctrl-C, the temporary file is removed and `path` is left untouched.
    """
    target = Path(path)
    folder = _folder(target)
    if not folder.is_dir():
        raise OutputError(f"cannot write {target}: folder {folder} does not exist")
    try:
        fd, tmp = tempfile.mkstemp(prefix=".posecam-", suffix=suffix or _suffix(target), dir=folder)
        os.close(fd)
    except OSError as exc:
        raise OutputError(f"cannot write {target}: {_describe(exc)}") from None
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        _commit(tmp_path, target)
    except OSError as exc:
        tmp_path.unlink(missing_ok=True)
        raise OutputError(f"cannot write {target}: {_describe(exc)}") from None
    except BaseException:
        tmp_path.unlink(missing_ok=True)
        raise


def _commit(tmp: Path, target: Path) -> None:
    """Flush `tmp` to disk and rename it onto `target`; a full disk shows here at the latest."""
    if not tmp.is_file():
        raise OutputError(f"cannot write {target}: the writer produced no file")
    with open(tmp, "rb+") as f:
        os.fsync(f.fileno())
    stats = os.statvfs(tmp)
    free = stats.f_bfree if os.geteuid() == 0 else stats.f_bavail
    if free == 0 and stats.f_blocks > 0:
        # Some writers (FFmpeg's) drop write errors; a disk left with no free block lost data.
        raise OSError(28, os.strerror(28))
    if tmp.suffix.lower() in VIDEO_SUFFIXES and not readable_video(tmp):
        # the same for other failures (a file size limit): a video that does not read back
        raise OutputError(f"cannot write {target}: the video does not read back (disk full or file too large?)")
    os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; give the usual permissions
    os.replace(tmp, target)


def write_text(path: str | os.PathLike, text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


class OutputSet:
    """All outputs of one command, committed together.

        with OutputSet([output, viz], inputs=[*inputs, intrinsics_file]) as out:
            write_poses(out.path(output), ...)        # a temporary path for each target
        # here every target exists, complete; after an error none was touched

    Targets that are None are skipped, so optional outputs can be passed as they are.
    """

    def __init__(self, targets: Iterable[str | os.PathLike | None],
                 inputs: Iterable[str | os.PathLike | None] = ()):
        inputs = [p for p in inputs if p is not None]
        self.targets: list[Path] = []
        for t in targets:
            if t is None:
                continue
            target = check_output(t, inputs)
            if any(same_file(target, other) for other in self.targets):
                raise OutputError(f"{target} is given as two outputs")
            self.targets.append(target)
        self._staged: dict[Path, Path] = {}
        self._folders: dict[Path, Path] = {}
        self._count = 0

    def __enter__(self) -> "OutputSet":
        return self

    def path(self, target: str | os.PathLike) -> Path:
        """The temporary path to write `target` to (one of the targets given)."""
        target = Path(target)
        if target not in self.targets:
            raise ValueError(f"{target} is not one of this command's outputs")
        if target not in self._staged:
            self._staged[target] = self.extra(target)
        return self._staged[target]

    def extra(self, target: str | os.PathLike) -> Path:
        """A temporary path for `target`, committed with the others; for files named by a
        writer rather than by the user, or registered later with `adopt`."""
        target = Path(target)
        self._count += 1
        return self._stage(_folder(target)) / f"{self._count}{_suffix(target)}"

    def adopt(self, target: str | os.PathLike, staged: Path) -> None:
        """Commit `staged` (a file a writer made inside the staging folder) as `target`."""
        self._staged[Path(target)] = staged

    def _stage(self, folder: Path) -> Path:
        key = folder.resolve()
        if key not in self._folders:
            try:
                self._folders[key] = Path(tempfile.mkdtemp(prefix=".posecam-", dir=folder))
            except OSError as exc:
                raise OutputError(f"cannot write in {folder}: {_describe(exc)}") from None
        return self._folders[key]

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        try:
            if kind is None:
                self._commit_all()
            elif issubclass(kind, PosecamError):   # name the user's file, not its temporary one
                message = str(exc)
                for target, tmp in self._staged.items():
                    message = message.replace(str(tmp), str(target))
                if message != str(exc):
                    raise kind(message) from None
        finally:
            for stage in self._folders.values():
                shutil.rmtree(stage, ignore_errors=True)

    def _commit_all(self) -> None:
        missing = [t for t in self.targets if t not in self._staged]
        if missing:
            raise OutputError(f"internal: no output was written for {missing[0]}")
        for target, tmp in self._staged.items():
            try:
                _commit(tmp, target)
            except OSError as exc:
                raise OutputError(f"cannot write {target}: {_describe(exc)}") from None
