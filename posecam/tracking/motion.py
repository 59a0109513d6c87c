"""The motion model of a followed person's box: a constant-velocity Kalman filter."""

from __future__ import annotations

import numpy as np

from posecam.tracking.policy import TRACKING


class BoxKalman:
    """Constant-velocity Kalman filter on (cx, cy, w, h), noise relative to the box height (as
    ByteTrack: TRACKING's position_noise, velocity_noise)."""

    POS, VEL = TRACKING.position_noise, TRACKING.velocity_noise

    def __init__(self, box: np.ndarray):
        self.x = np.concatenate([_xywh(box), np.zeros(4)])
        h = self.x[3]
        self.p = np.diag(np.square([2 * self.POS * h] * 4 + [10 * self.VEL * h] * 4))
        self.f = np.eye(8)
        self.f[:4, 4:] = np.eye(4)

    def predict(self, keep_size: bool = False) -> None:
        """Move the box on a frame; `keep_size`: its size stops changing (someone unseen: a box
        shrinking or growing on its last velocity would soon be no one's; ByteTrack does the same)."""
        if keep_size:
            self.x[6:] = 0.0
        h = self.x[3]
        q = np.diag(np.square([self.POS * h] * 4 + [self.VEL * h] * 4))
        self.x = self.f @ self.x
        self.p = self.f @ self.p @ self.f.T + q

    def update(self, box: np.ndarray) -> None:
        r = np.diag(np.square([self.POS * self.x[3]] * 4))
        s = self.p[:4, :4] + r
        gain = np.linalg.solve(s, self.p[:4, :]).T
        self.x = self.x + gain @ (_xywh(box) - self.x[:4])
        self.p = self.p - gain @ self.p[:4, :]

    @property
    def box(self) -> np.ndarray:
        cx, cy, w, h = self.x[:4]
        return np.array([cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2])


def _xywh(box: np.ndarray) -> np.ndarray:
    return np.array([(box[0] + box[2]) / 2, (box[1] + box[3]) / 2, box[2] - box[0], box[3] - box[1]], float)
