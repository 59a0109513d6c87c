"""Outputs appear complete or not at all.

- `atomic_path(path)`: one file, written to a temporary name beside it and renamed on success.
- `OutputSet`: every output of one command, known and checked before the work (folder exists,
  not a folder itself, not one of the inputs; per-person marker files `FILE_id<ID>.trc` by their
  pattern), written to temporary names in a hidden staging folder beside each target, and
  committed together only when the whole command succeeded: every staged file is verified
  (flushed, a video read back), every target checked again (the file system may have changed
  during the work), then renamed; a rename that fails puts back the targets already replaced.
  On any error, Ctrl-C or SIGTERM (which the CLI turns into an exception) the staging folder
  is removed and no target is touched.

Temporary names start `.posecam-<pid>-`, are short and ASCII and keep the target's extension
(writers such as OpenCV's pick the format from it), so a 255-byte target name works and OpenCV
never sees a name it cannot encode. Ones whose process is gone (a run killed with SIGKILL) are
removed by the next run writing in that folder. A task of a batch run stages under its run's
tag as well (`tagged_staging`), so that the run removes what a task it had to kill left
(`remove_run_staging`), and its worker verifies but does not rename (`deferred_commit`): it
hands the `StagedOutputs` to the run's own process, which commits them only while no signal
came, so nothing appears after a Ctrl-C however late the worker hears of it. Every OSError
while writing becomes an `OutputError` (exit code 4) naming the target.
"""

from __future__ import annotations

import errno
import os
import re
import shutil
import signal
import tempfile
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType

from posecam.errors import WRITE_ERRNOS, OutputError, PosecamError, ReaderLeft, printable, raise_if_signalled, warn
from posecam.io.media import VIDEO_SUFFIXES, readable_video

_MAX_SUFFIX = 16   # longer "extensions" are not kept in temporary names
_STALE = re.compile(r"^\.posecam-(\d+)-")
_run_tag = ""   # inside `tagged_staging`: the batch run whose task this process is running
_deferred: list[StagedOutputs] | None = None   # inside `deferred_commit`: output sets left to commit


def _folder(target: Path) -> Path:
    return target.parent if str(target.parent) else Path(".")


def _suffix(target: Path) -> str:
    suffix = target.suffix
    return suffix if len(suffix) <= _MAX_SUFFIX and suffix.isascii() else ""


def _prefix() -> str:
    return f".posecam-{os.getpid()}-{_run_tag}"


@contextmanager
def tagged_staging(tag: str) -> Iterator[None]:
    """Inside the block, temporary names carry the batch run's `tag` (short, ASCII letters and
    digits) after the pid: `.posecam-<pid>-<tag>-...`."""
    global _run_tag
    _run_tag = f"{tag}-"
    try:
        yield
    finally:
        _run_tag = ""


@contextmanager
def deferred_commit() -> Iterator[list[StagedOutputs]]:
    """Inside the block, an `OutputSet` that succeeds is verified and left staged, not renamed:
    it is appended to the list yielded, for the process that owns the run to `commit`."""
    global _deferred
    _deferred = []
    try:
        yield _deferred
    finally:
        _deferred = None


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _describe(exc: OSError) -> str:
    return exc.strerror or str(exc)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:   # another user's process
        return True
    return True


def _entries(folder: str | os.PathLike, pattern: re.Pattern) -> list[os.DirEntry]:
    try:
        return [e for e in os.scandir(folder) if pattern.match(e.name)]
    except OSError:
        return []


def remove_stale(folder: str | os.PathLike) -> None:
    """Remove the temporary files and staging folders that a killed posecam run left in
    `folder` (their process is gone), with a warning naming each."""
    for entry in _entries(folder, _STALE):
        if not _alive(int(_STALE.match(entry.name).group(1))) and _remove(Path(folder) / entry.name, entry):
            warn(f"removed {printable(Path(folder) / entry.name)}, left over from an interrupted posecam run")


def remove_run_staging(folder: str | os.PathLike, tag: str) -> None:
    """Remove what the tasks of batch run `tag` staged in `folder` (once they have all ended:
    a task killed before its clean-up leaves its staging folder)."""
    for entry in _entries(folder, re.compile(rf"^\.posecam-\d+-{re.escape(tag)}-")):
        _remove(Path(folder) / entry.name, entry)


def _remove(path: Path, entry: os.DirEntry) -> bool:
    """Remove a temporary file or staging folder; False, with a warning, if it cannot be."""
    try:
        if entry.is_dir(follow_symlinks=False):
            shutil.rmtree(path)
        else:
            path.unlink()
    except FileNotFoundError:    # its own process removed it meanwhile
        return False
    except OSError as exc:
        warn(f"{printable(path)} is left over from an interrupted posecam run and cannot be removed "
             f"({_describe(exc)}); remove it")
        return False
    return True


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
    try:
        os.stat(target)   # ENAMETOOLONG and ELOOP show here, before any work
    except FileNotFoundError:
        pass
    except OSError as exc:
        raise OutputError(f"cannot write {target}: {_describe(exc)}") from None
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


def per_person_pattern(path: str | os.PathLike) -> re.Pattern:
    """The names of the per-person files of marker output `path` (NAME_id<ID>.trc)."""
    path = Path(path)
    return re.compile(re.escape(path.stem) + r"_id\d+" + re.escape(path.suffix) + r"\Z")


@contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path in the target's folder; rename it onto `path` on success.

    On any error, including Ctrl-C, the temporary file is removed and `path` is left untouched.
    """
    target = Path(path)
    folder = _folder(target)
    if not folder.is_dir():
        raise OutputError(f"cannot write {target}: folder {folder} does not exist")
    held = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})   # as in OutputSet._stage
    try:
        fd, tmp = tempfile.mkstemp(prefix=_prefix(), suffix=_suffix(target), dir=folder)
        os.close(fd)
    except OSError as exc:
        raise OutputError(f"cannot write {target}: {_describe(exc)}") from None
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, held)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        raise_if_signalled()
        _verify(tmp_path, target)
        _publish(tmp_path, target)
        if not any(_STALE.match(part) for part in Path(target).parts):   # a staged file is not an output yet
            _committed.append(target)
    except BaseException as exc:
        tmp_path.unlink(missing_ok=True)
        if isinstance(exc, OSError):
            raise OutputError(f"cannot write {target}: {_describe(exc)}") from None
        raise


_committed: list[Path] = []   # every output this process committed, in order


def committed() -> list[Path]:
    """The outputs this process has committed so far (a signal after them names them)."""
    return list(_committed)


def _verify(tmp: Path, target: Path) -> None:
    """Flush `tmp` to disk and check it; a full disk shows here at the latest."""
    if not tmp.is_file():
        raise OutputError(f"cannot write {target}: the writer produced no file")
    with open(tmp, "rb+") as f:
        os.fsync(f.fileno())
    stats = os.statvfs(tmp)
    free = stats.f_bfree if os.geteuid() == 0 else stats.f_bavail
    if free == 0 and stats.f_blocks > 0:
        # Some writers (FFmpeg's) drop write errors; a disk left with no free block lost data.
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    if tmp.suffix.lower() in VIDEO_SUFFIXES and not readable_video(tmp):
        # the same for other failures (a file size limit): a video that does not read back
        raise OutputError(f"cannot write {target}: the video does not read back (disk full or file too large?)")
    os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; give the usual permissions


def _publish(tmp: Path, target: Path) -> None:
    if target.is_dir():   # os.replace would put a file into an empty folder's place
        raise OutputError(f"cannot write {target}: a folder appeared there during the run")
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
    `per_person` is a marker output (FILE.trc or FILE.c3d) written as one file per person:
    FILE itself or FILE_id<ID>.trc, whose ids are known only after the work; its folder, and
    every input and existing entry the pattern could name, are checked now.
    """

    def __init__(self, targets: Iterable[str | os.PathLike | None],
                 inputs: Iterable[str | os.PathLike | None] = (),
                 per_person: str | os.PathLike | None = None):
        self.inputs = [p for p in inputs if p is not None]
        self.targets: list[Path] = []
        for t in targets:
            if t is None:
                continue
            target = check_output(t, self.inputs)
            if any(same_file(target, other) for other in self.targets):
                raise OutputError(f"{target} is given as two outputs")
            self.targets.append(target)
        self.per_person = self._check_per_person(Path(per_person)) if per_person is not None else None
        self._staged: dict[Path, Path] = {}
        self._folders: dict[Path, Path] = {}
        self._count = 0
        for folder in {_folder(t).resolve() for t in self.targets + ([self.per_person] if self.per_person else [])}:
            remove_stale(folder)

    def _check_per_person(self, path: Path) -> Path:
        check_output(path, self.inputs)
        pattern = per_person_pattern(path)
        for source in self.inputs:
            if pattern.match(Path(source).name) and same_file(_folder(Path(source)), _folder(path)):
                raise OutputError(f"refusing to overwrite the input {source} with an output "
                                  f"(one file per person: {path.stem}_id<ID>{path.suffix})")
        for other in self.targets:
            if pattern.match(other.name) and same_file(_folder(other), _folder(path)):
                raise OutputError(f"{other} is given as two outputs (one file per person of {path})")
        return path

    def _is_target(self, target: Path) -> bool:
        if target in self.targets:
            return True
        p = self.per_person
        return p is not None and (target == p or (target.parent == p.parent
                                                  and bool(per_person_pattern(p).match(target.name))))

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
        """A temporary path for `target`, committed with the others once `adopt`ed: for files
        named by a writer (the per-person files, an int8 copy) rather than by the user."""
        target = Path(target)
        self._count += 1
        return self._stage(_folder(target)) / f"{self._count}{_suffix(target)}"

    def adopt(self, target: str | os.PathLike, staged: Path) -> None:
        """Commit `staged` (a file a writer made inside the staging folder) as `target`, which
        must be a target given or one of the per-person files."""
        target = Path(target)
        if not self._is_target(target):
            raise ValueError(f"{target} is not one of this command's outputs")
        self._staged[target] = staged

    def _stage(self, folder: Path) -> Path:
        key = folder.resolve()
        if key not in self._folders:
            # a Ctrl-C between making the folder and noting it would leave it behind: held back
            held = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
            try:
                self._folders[key] = Path(tempfile.mkdtemp(prefix=_prefix(), dir=folder))
            except OSError as exc:
                raise OutputError(f"cannot write in {folder}: {_describe(exc)}") from None
            finally:
                signal.pthread_sigmask(signal.SIG_SETMASK, held)
        return self._folders[key]

    def _name_target(self, exc: OSError) -> Path | None:
        """The target an OSError inside the block was writing, if it was an output's."""
        for target, tmp in self._staged.items():
            if exc.filename is not None and os.fspath(exc.filename) == str(tmp):
                return target
        if exc.errno in WRITE_ERRNOS and self._staged:
            return list(self._staged)[-1]
        return None

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        try:
            if kind is None or issubclass(kind, ReaderLeft):
                # a closed stdout (`| head`) is the reader leaving, not a failed output
                staged = self._verified()
                if _deferred is None:
                    staged.commit()
                else:   # the run's own process commits or removes them
                    _deferred.append(staged)
                    self._folders = {}
            elif issubclass(kind, PosecamError):   # name the user's file, not its temporary one
                message = str(exc)
                for target, tmp in self._staged.items():
                    message = message.replace(str(tmp), str(target))
                if message != str(exc):
                    raise kind(message) from None
            elif issubclass(kind, OSError):
                target = self._name_target(exc)
                if target is not None:
                    raise OutputError(f"cannot write {target}: {_describe(exc)}") from None
        finally:
            for stage in self._folders.values():
                shutil.rmtree(stage, ignore_errors=True)

    def _verified(self) -> StagedOutputs:
        raise_if_signalled()   # a Ctrl-C that a library swallowed still stops the commit
        missing = [t for t in self.targets if t not in self._staged]
        if missing:
            raise OutputError(f"internal: no output was written for {missing[0]}")
        for target, tmp in self._staged.items():   # every file complete and flushed
            try:
                _verify(tmp, target)
            except OSError as exc:
                raise OutputError(f"cannot write {target}: {_describe(exc)}") from None
        return StagedOutputs(list(self._staged.items()), self.inputs, list(self._folders.values()))


@dataclass
class StagedOutputs:
    """An `OutputSet`'s verified files, still in their staging folders: (target, staged) pairs."""
    files: list[tuple[Path, Path]]
    inputs: list[str | os.PathLike]
    folders: list[Path]

    def commit(self) -> None:
        """Every target checked again, then all renamed or none; the staging folders go."""
        try:
            raise_if_signalled()
            for target, _ in self.files:
                check_output(target, self.inputs)
            self._rename_all()
        finally:
            for stage in self.folders:
                shutil.rmtree(stage, ignore_errors=True)

    def _rename_all(self) -> None:
        done: list[tuple[Path, Path | None]] = []
        try:
            for target, tmp in self.files:
                backup = self._backup(target, tmp)
                done.append((target, backup))
                _publish(tmp, target)
            _committed.extend(target for target, _ in self.files)
        except BaseException as exc:
            failed = done[-1][0] if done else None
            for target, backup in reversed(done):
                if backup is not None:
                    os.replace(backup, target)
                elif target.is_file() and target != failed:
                    target.unlink(missing_ok=True)
            if isinstance(exc, OSError):
                raise OutputError(f"cannot write {failed}: {_describe(exc)}") from None
            raise

    @staticmethod
    def _backup(target: Path, tmp: Path) -> Path | None:
        """A hard link to the file `target` replaces, in the staging folder, to put it back if a
        later rename fails; None when there is no such file."""
        if not target.is_file():
            return None
        backup = tmp.with_name(tmp.name + ".old")
        try:
            os.link(target, backup)
        except OSError:              # no hard links here: move it aside instead
            os.replace(target, backup)
        return backup
