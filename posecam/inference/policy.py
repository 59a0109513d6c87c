"""The rules of the stages before the pose model: the detector's (`DETECTION`), the crops'
(`CROP`) and the light's (`LIGHT`), each threshold once with what set it. vtest.avi's runs and
the photos are docs/benchmarks.md's; "by hand": chosen, not measured."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class DetectorPolicy:
    movenet_score: float = 0.25         # a MoveNet detection this confident starts a track: people from behind or half hidden score 0.3-0.5
    weak_share: float = 1 / 3           # down to this share of the start score a detection keeps a track alive (by hand)
    blazepose_score: float = 0.5        # a BlazePose detection this confident starts a track (MediaPipe's)
    blazepose_nms_iou: float = 0.3      # BlazePose's anchors over this IoU are one person (MediaPipe's)
    found_px: float = 50                # a person this tall in the input is found confidently: vtest.avi's hand counts (bench_people.py)
    max_tiles: int = 3                  # tiles a side at most (by hand; 3 x 3 on vtest.avi's 40 px people: 65/81 found, 0.5 s)
    tile_overlap: float = 0.25          # each tile reaches this share of its side into its neighbours (by hand)
    tile_edge: float = 0.01             # a box this close to a tile's inner edge (of the tile's side) is left to a run that holds it whole
    merge_iou: float = 0.5              # detections whose boxes overlap over this IoU are one person (by hand) ...
    merge_oks: float = 0.5              # ... or whose keypoints agree over this OKS: one cut by a tile's edge (by hand)
    border_gap: float = 0.1             # a box this close to the border (of its longer side) may be cut by it (by hand)
    border_score: float = 0.6           # its score is raised by 1 / this: cut in half, basketball1/2, messi5 score a third (0.67 -> 0.23)
    seen_keypoint_score: float = 0.3    # a keypoint counts as seen from this score wherever people are matched by keypoints (by hand)


@dataclass(frozen=True)
class CropPolicy:
    keypoint_score: float = 0.4         # keypoints that place a crop need this score: a wrong one turns or stretches it (by hand)
    reach_margin: float = 1.0           # a body crop's radius over the farthest seen keypoint's distance from the hips (head top, feet)
    torso_reach: float = 1.6            # ... at least this many hip-to-shoulder lengths: legs hidden (by hand)
    max_box_ratio: float = 1.6          # a crop over this times its box's longer side is guessed keypoints: the box's (upright: 1.3)
    cut_reach: float = 1.6              # the crop of someone the border cuts, over their box's longer side (by hand) ...
    cut_pad: float = 0.1                # ... its inner sides this far past the box's (by hand)


@dataclass(frozen=True)
class LightPolicy:
    dark: float = 0.25                  # a frame whose median lightness is under this share of white is dark (by hand)
    clip: float = 3.0                   # CLAHE's clip limit (by hand; the dusk clip's joints 2.0-2.2 % off daylight's from 1 to 10)
    tiles: int = 8                      # CLAHE's tiles a side (OpenCV's default; 1 or 2 pose the dusk clip as well)
    sample: int = 8                     # the lightness is read on every this-th pixel of each axis: 0.4 ms a frame


DETECTION = DetectorPolicy()
CROP = CropPolicy()
LIGHT = LightPolicy()
