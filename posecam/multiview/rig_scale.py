"""An estimated rig at the people's given heights (`to_metric`). Without heights the bundle
adjustment's scale stays, the one the monocular bone lengths set."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from posecam.geometry.camera import Rig
from posecam.multiview.calibrate import KeptCameras, measured_statures
from posecam.multiview.observations import Observations, Take
from posecam.multiview.options import FuseOptions
from posecam.multiview.policy import CALIBRATION


def to_metric(cameras: KeptCameras, people: list[Observations], take: Take,
              opts: FuseOptions) -> tuple[KeptCameras, str, list[str]]:
    """Estimated cameras at the people's given heights (one similarity about the reference
    camera, reprojection unchanged), what fixes the scale and a warning where the heights given
    disagree with the relative heights the rig measures (given / measured spread by more than
    CALIBRATION.heights_agree: no one scale fits them all).
    The rig gives the people's relative heights exactly (`measured_statures`: its geometry alone,
    not the monocular skeletons' adult size); a list is matched tallest first
    (posecam.scale.heights) and the factor is the median of given / measured.
    Without heights the cameras stay (the bundle adjustment's scale, from the monocular bone lengths)."""
    estimated = measured_statures(cameras.rig, people, take.joints, opts.min_conf)
    given = opts.heights.assign(estimated) if opts.heights else {}
    if not given:
        return cameras, "the tallest person's bone lengths from the pose model (an adult's; --height gives it)", []
    ratios = [m / estimated[pid] for pid, (m, _) in given.items()]
    factor = float(np.median(ratios))
    people_text = ", ".join(f"person {pid} {m:.2f} m ({how})" for pid, (m, how) in sorted(given.items()))
    warnings = []
    if max(ratios) > (1 + CALIBRATION.heights_agree) * min(ratios):
        measured = ", ".join(f"person {pid} {estimated[pid] * factor:.2f} m (given {m:.2f})"
                             for pid, (m, _) in sorted(given.items()))
        warnings.append(f"the heights given disagree with the people's relative heights, which the cameras "
                        f"measure: at the scale used, {measured}; check --height")
    source = f"the heights given: {people_text}"
    if factor == 1.0:
        return cameras, source, warnings
    rig = Rig([replace(c, translation=c.translation * factor) for c in cameras.rig.cameras], cameras.rig.reference)
    spreads = cameras.spreads and [replace(c, position_mm=c.position_mm * factor) for c in cameras.spreads]
    return replace(cameras, rig=rig, spreads=spreads), source, warnings
