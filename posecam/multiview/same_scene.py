"""Whether views show one scene: their people's motion agrees at the offsets (what the
calibration's gate reads, posecam.multiview.calibrate). Views of one scene move alike;
unrelated clips, whose people any rig can be bent to fit, do not.
"""

from __future__ import annotations

from posecam.multiview.motion_sync import motion_correlation, shared_motion
from posecam.multiview.observations import PersonTracks, Take


def motion_agreement(take: Take, people: list[PersonTracks], offsets: list[float],
                     min_conf: float) -> dict[int, tuple[float, float]]:
    """Per view: the correlation of its people's motion with the reference's at its offset, and
    their excursion (mm). Views of one scene move alike; unrelated clips, whose people any rig
    can be bent to fit, do not."""
    out = {}
    for v in range(len(take.names)):
        shared = shared_motion(take, people, v, min_conf) if v != take.reference else None
        if shared is not None:
            out[v] = (motion_correlation(shared[0], shared[1], offsets[v]), shared[2])
    return out
