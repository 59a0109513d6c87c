"""Whether views show one scene: their people's motion agrees at the offsets (what the
calibration's gate reads, posecam.multiview.calibrate). Views of one scene move alike;
unrelated clips, whose people any rig can be bent to fit, do not.
"""

from __future__ import annotations

from posecam.multiview.motion_sync import motion_correlation, shared_motion
from posecam.multiview.observations import PersonTracks, Take

# views of one scene move alike: the joint speeds of the people two views share correlate by
# 0.37-0.83 on Pose2Sim's takes (each pair of cameras, at the offsets found); unrelated walkers
# can too (OpenCV's vtest.avi against itself 40 s later: 0.61 at the best of a wide search,
# refused by the bootstrap instead): below this the views are not fused, one scene or not
MIN_SAME_MOTION = 0.38


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
