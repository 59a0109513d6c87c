"""The recordings checked as one take's views (`check_take` -> Take), or refused in one line:
fewer than two, other skeletons, frame rates or lengths that do not line up, no one in a view,
no intrinsics, one recording given twice."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from posecam.errors import FusionError, InputError
from posecam.multiview.observations import Take
from posecam.multiview.options import FuseOptions
from posecam.multiview.policy import SYNC, TAKE
from posecam.results import Recording


def view_names(recordings: list[Recording]) -> list[str]:
    """Camera names: the input file stems, made unique."""
    names = []
    for r in recordings:
        stem = Path(r.source).stem or "view"
        names.append(stem if stem not in names else f"{stem}_{len(names)}")
    return names


REFERENCE = 0       # the view whose camera and frames the fused recording is in: the first


def check_lengths(names: list[str], lengths: list[int], opts: FuseOptions) -> str | None:
    """Views of different lengths are what cameras started and stopped by hand give: lined up
    by offsets found without a calibration, or by the offsets given, which must leave each view
    TAKE.min_shared of its frames (or of the reference's, if fewer) in common with the reference
    (REFERENCE); a warning line says they differ. Views taken as started together (no offsets, no search
    without a calibration) may differ by at most the search of a calibrated sync (`max_offset`):
    InputError past what they allow."""
    sync = opts.finds_offsets
    if not lengths or max(lengths) == min(lengths) or (sync and not opts.synchronised_rig):
        return None
    shown = ", ".join(f"{n} {k}" for n, k in zip(names, lengths))
    if opts.offsets is not None and len(opts.offsets) == len(lengths):
        ref, o_ref = lengths[REFERENCE], opts.offsets[REFERENCE]
        for name, n, o in zip(names, lengths, opts.offsets):       # reference frames i with i + o in the view
            shared = max(0, int(np.floor(min(ref, n - (o - o_ref)) - max(0.0, o_ref - o))))
            if shared < TAKE.min_shared * min(n, ref):
                raise InputError(f"the views have different lengths ({shown} frames) and at the offsets given "
                                 f"{name} shares only {shared} of its frames with {names[REFERENCE]}: "
                                 "check --offsets, or fuse recordings of the same take")
    else:
        search = opts.max_offset if opts.max_offset is not None else SYNC.rig_max_offset if sync else 0
        if max(lengths) - min(lengths) > search:
            raise InputError(f"the views have different lengths ({shown} frames): fuse needs "
                             "recordings of the same take; trim them to it, or give --offsets")
    return (f"the views differ in length ({shown} frames): fuse lines them up by their first frames "
            "(shifted by --offsets or --sync auto); are they one take?")


def check_take(recordings: list[Recording], opts: FuseOptions) -> Take:
    """The recordings as one take's views (posecam.multiview.observations.Take; its warnings: the
    views' lengths differ, `check_lengths`), or InputError / FusionError saying why they are not."""
    if len(recordings) < 2:
        raise InputError(f"fusion needs two views or more, got {len(recordings)}")
    if len({r.joints for r in recordings}) != 1:
        raise InputError("the views were predicted with different skeletons; predict them with the same --skeleton")
    if opts.offsets is not None and len(opts.offsets) != len(recordings):
        raise InputError(f"--offsets needs one value per view ({len(recordings)}), got {len(opts.offsets)}")
    names = view_names(recordings)
    differ = check_lengths(names, [len(r.frames) for r in recordings], opts)
    rates = [r.fps for r in recordings if r.fps]
    if rates and max(rates) > TAKE.fps_tolerance * min(rates):
        raise InputError(f"the views have different frame rates ({', '.join(f'{f:g}' for f in rates)} fps)")
    for name, r in zip(names, recordings):
        if not any(f.people for f in r.frames):
            raise FusionError(f"no person found in view {name}")
        if r.intrinsics is None:
            raise InputError(f"view {name} has no intrinsics")
    for a, b in _twins(recordings):
        raise FusionError(f"views {names[a]} and {names[b]} hold the same poses (one recording given twice?): "
                          "fusion needs different cameras")
    take = Take.of(names, recordings, REFERENCE)
    take.warnings = [differ] if differ else []
    return take


def _twins(recordings: list[Recording], max_px: float = TAKE.twin_px) -> list[tuple[int, int]]:
    """Pairs of views whose people sit at the same pixels in most frames they both have."""
    people = [{i: np.stack([p.keypoints_2d for p in f.people]) for i, f in enumerate(r.frames) if f.people}
              for r in recordings]
    out = []
    for a in range(len(recordings)):
        for b in range(a + 1, len(recordings)):
            common = sorted(set(people[a]) & set(people[b]))[:TAKE.twin_frames]
            same = [_closest(np.linalg.norm(people[a][i][:, None] - people[b][i][None], axis=-1)) < max_px
                    for i in common]
            if same and np.mean(same) > TAKE.twin_share:
                out.append((a, b))
    return out


def _closest(distances: np.ndarray) -> float:
    """The smallest median over joints of (Pa, Pb, J) distances between two views' people
    (inf where no pair shares a joint: people whose joints a file left null)."""
    seen = np.isfinite(distances).any(axis=-1)
    return float(np.nanmedian(distances[seen], axis=-1).min()) if seen.any() else np.inf

