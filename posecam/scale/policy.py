"""The metric scale's rules, one frozen policy per stage, each value with why it is what it is and
what it was measured on ("set by hand": nothing measured it yet): `ScalePolicy` (posecam.scale.metric,
the stance of .stature) and `LensPolicy` (.lens). The code reads the default instances, `SCALE` and
`LENS`. Physical and anthropometric constants and the pose models' measured sizes stay by their code."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class ScalePolicy:
    """Each person's metric size (posecam.scale.metric) and stance (.stature)."""

    samples: int = 512              # frames a track keeps for its statistics (a median; set by hand)
    lens_samples: int = 64          # upright frames a track keeps for the lens: its bootstrap stays quick (set by hand)
    refit_every: int = 30           # frames between fits of the floor, and at the end (set by hand)
    model_sd: float = 0.06          # relative sd of the model's adult size, one person (its skeletons: 1.5 %; by hand)
    # relative sd of a root depth a given height scales: RMS per-frame depth error against the lab, heights given, over
    # the Pose2Sim takes' views (the 1.72 m man's 8: 0.049; the 1.40 m woman's 4: 0.071): the model's error in that view
    given_sd: float = 0.057
    # a track further than this from the model's size was measured on mis-posed frames (2 frames of a man cut at the
    # knees: 34 % short); whole people's tracks over both takes' 40 views lie within 3.3 % of it
    size_off: float = 0.12
    # a track measured on fewer than this share of its frames has its legs out of view (cam02 of the single take, cut at
    # the knees: 5 of 100, made 1.27 m by a floor); whole people's tracks (both takes, vtest.avi) 51-100 %
    seen_share: float = 0.25
    min_track_contacts: int = 5     # foot contacts a track needs for the floor to scale it (set by hand)
    adult_cluster: float = 0.85     # tracks this share of the tallest or more gauge the floor: the adults (set by hand)
    # confident trunk and leg joints that place a root again: the trunk's corners alone for legs out of view (both
    # takes' views cut at the knees: mean depth error 188 -> 169 mm with 4 for 6, single take; plain views within 1 mm)
    core_joints: int = 4
    lens_disagrees: float = 2.0     # sds between the default lens and the people's for a warning (set by hand)
    # statures (m) a floor may give the people it measures, a 4-year-old to the tallest adults: a plane that makes
    # anyone shorter or taller is feet cut by the border or off the ground, not a floor
    floor_stature_m: tuple[float, float] = (1.0, 2.3)
    straight_legs: float = 0.95     # hip-ankle over hip-knee-ankle at least this: legs straight, standing (set by hand)
    upright_deg: float = 20.0       # the torso within this of the head-to-feet line: standing upright (set by hand)


@dataclass(frozen=True)
class LensPolicy:
    """The focal length from upright people (posecam.scale.lens)."""

    min_lines: int = 20             # upright people's head-to-feet lines the vanishing point needs (set by hand)
    min_horizon: int = 10           # horizon points (a track's heads and feet at two places) it needs (set by hand)
    max_focal_sd: float = 0.10      # relative sd above which the people's lens is refused (the default's: 30 %)
    min_spread: float = 0.15        # the feet's span (5-95 %, image heights): less, verticals barely meet (set by hand)
    chunk: int = 10                 # consecutive samples resampled together where tracks are few (set by hand)
    reweights: int = 3              # fits of the vanishing point, each reweighted against the last one's outliers
    max_vanishing: float = 50.0     # image heights: a vanishing point further is at infinity (a camera looking level)
    beyond_feet: float = 0.9        # share of the verticals that must meet beyond the feet, not among the people
    depth_apart: float = 0.05       # image heights between a track's two places' feet for a horizon point (set by hand)
    whole_tracks: int = 5           # tracks the bootstrap resamples whole; with fewer, chunks of their samples
    bootstrap: int = 50             # resamples for the focal length's sd: its own error 1 / sqrt(2 * 50) = 10 %
    min_bootstrap: int = 10         # resamples that must find a focal length, else it is not pinned (set by hand)


SCALE = ScalePolicy()
LENS = LensPolicy()
