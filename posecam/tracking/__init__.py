"""People followed over the frames of a video: ByteTrack-style multi-object tracking.

Each track (`track.Track`) keeps a key, a constant-velocity Kalman filter on its box (`motion`:
centre, size; the size stops changing while the person is unseen), its last keypoints and the
ROI where the pose model looks next; the person's id (`Track.number`) is numbered only once the
track is confirmed (`confirm_hits`, `confirm_frames`): a track lost before that is a false start
and forgotten at once, and `ids.ConfirmedIds` holds a video's frames back until their people are
decided. On a detector frame the tracks are matched to the detections in two stages
(ByteTrack, `assignment`): first the confident detections, then the weak ones against the tracks
left over, each by the Hungarian method on a cost that mixes box overlap (IoU) and keypoint
similarity (OKS). Hysteresis: only a confident detection starts a track, a weak one keeps it
alive, and an unmatched track can be matched by its motion for `max_lost` frames. Between
detector frames each track's ROI comes from its previous pose. Someone the pose model lost is
looked for again by it for `probe_frames` frames, where their motion puts them and nobody else
followed is (`Tracker.probes`): the detector may not see them there (backlit, in the dark).
With an embedder the looks weigh in where the motion is ambiguous and bring back people lost
(`reid`).

The tracker also says when to run the detector and where (`schedule`: `Tracker.detector_run`,
`Tracker.search`, the search handed back to `Tracker.begin_frame`), and how small the people it
has seen are, which sets how finely the detector's tiles cut the image.

Modules, each importing only those below it: tracker and ids on top, then schedule and reid,
assignment, track, motion; every threshold is the policy's (`policy.TRACKING`).
"""

from posecam.inference.detector import oks
from posecam.tracking.assignment import foreign_joints, min_cost_assignment, unambiguous_pairs
from posecam.tracking.ids import ConfirmedIds, number_people
from posecam.tracking.motion import BoxKalman
from posecam.tracking.policy import TRACKING, TrackingPolicy
from posecam.tracking.schedule import DetectorRun, Search
from posecam.tracking.track import Track, TrackerOptions
from posecam.tracking.tracker import Tracker

__all__ = ["TRACKING", "BoxKalman", "ConfirmedIds", "DetectorRun", "Search", "Track", "Tracker", "TrackerOptions",
           "TrackingPolicy", "foreign_joints", "min_cost_assignment", "number_people", "oks", "unambiguous_pairs"]
