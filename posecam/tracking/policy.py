"""The tracker's rules: every threshold of posecam.tracking, once, with what set it.

The tracker follows `TRACKING` unless given another (`Tracker(policy=...)`, e.g.
`dataclasses.replace(TRACKING, coast=2)`); a track's own rules (`Track.take`, `BoxKalman`) and
`foreign_joints` follow `TRACKING`. vtest.avi's runs are docs/benchmarks.md's ("The search",
"Ids", "Someone lost, looked for again"); "by hand": chosen, not measured.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class TrackingPolicy:
    # when and where the detector runs (schedule)
    search_every: float = 0.5        # s between searches everywhere while people may be missing: vtest 74/81 found (0.3 s: 73, 0.8 s: 70)
    search_pad: float = 0.5          # a search about someone reaches this many heights past their box (0.15 kept no more of cam03's adult)
    search_span: float = 4.0         # ... about several, at most this many heights of the smallest (a quarter of the input's side; by hand)
    min_region_px: int = 16          # a search region narrower than this, clipped at the border, is not searched (by hand)
    whole_share: float = 0.5         # regions over this share of the image give way to it whole: regions lost 3 of cam03's people
    crowd: int = 3                   # this many people followed are a crowd, searched every search_every (by hand)
    walking: float = 0.005           # box heights a frame: someone at the edge moving faster enters or leaves (standing there is neither)
    edge: float = 0.05               # a box this close to the border (of the image's side) is at its edge (by hand)
    # ids: confirmed, kept, looked for again
    confirm_hits: int = 3            # detections that confirm a track (or no miss since): vtest ids 31 -> 29 numbered at confirmation
    confirm_frames: int = 10         # frames followed before an id; a frame waits at most this for its people's ids (same run)
    max_lost: int = 30               # frames a track survives unseen, carried by its motion (ByteTrack's track buffer)
    coast: int = 4                   # detector runs in a row that may miss someone the pose model still follows (by hand)
    probe_frames: int = 30           # frames the pose model looks again for someone lost: the hidden-then-backlit clip 30 -> 72/80 frames
    # matching by motion
    match_cost: float = 0.8          # 1 - similarity above which a confident detection matches no track (ByteTrack's first stage)
    low_match_cost: float = 0.5      # ... a weak one (ByteTrack's second stage)
    out_of_gate: float = 1.0         # added to a pair out of the motion gate: over any cost mixed with looks (<= 1), so none loses to it
    same_pose: float = 0.7           # OKS over which a pose duplicates an older track's (by hand)
    foreign_near: float = 0.15       # a joint this near a neighbour's keypoint (of the own box's diagonal) ...
    foreign_off: float = 0.1         # ... and this far off the own detection's lies on the neighbour (by hand)
    turned: float = np.pi / 3        # rad off upright over which a followed person keeps their crop: athlete 69-165 deg; 49, the leaning adult, out
    position_noise: float = 1 / 20   # the box filter's noise on position, of the box's height (ByteTrack's)
    velocity_noise: float = 1 / 160  # ... on velocity (ByteTrack's)
    # looks (reid)
    reid_seconds: float = 10.0       # s a lost person is remembered for their looks: vtest 30 s gave a woman's id to a man
    unlike: float = 0.35             # cosine distance of looks over which a lost person's motion match is refused (vtest, was 0.4)
    reid_distance: float = 0.3       # ... under which a lost person is recognised: vtest 0.4 without a margin recognised others
    reid_colour: float = 0.2         # ... if the clothes' colours alone are this near too (vtest's contact sheets)
    reid_height: float = 1.6         # ... if their heights differ by less than this factor (by hand)
    reid_speed: float = 1.0          # ... and they are within (1 + this x seconds lost) heights: nobody walks a height a second faster
    reid_margin: float = 0.05        # ... and nobody else is within this of the same match (vtest: no margin, someone else's id)
    appearance_weight: float = 0.5   # share of the looks in an ambiguous motion match's cost (by hand)
    gallery: int = 8                 # appearance vectors kept a track (by hand)
    refresh_every: int = 10          # frames between a matched track's new appearance vectors (by hand)


TRACKING = TrackingPolicy()
