import numpy as np

from posecam.inference.roi import Roi


def test_crop_and_map_back_with_rotation():
    image = np.zeros((400, 600, 3), np.uint8)
    image[250:254, 380:384] = 255                     # a bright dot centred at (381.5, 251.5)
    roi = Roi.from_alignment_points(np.array([300.0, 200.0]), np.array([350.0, 120.0]))
    crop = roi.crop(image, 256)
    ys, xs = np.nonzero(crop[..., 0] > 60)
    found = np.array([xs.mean(), ys.mean()])
    assert np.abs(roi.to_image(found, 256) - [381.5, 251.5]).max() < 1.0


def test_alignment_points_make_the_body_upright():
    # scale point straight above the hip centre: no rotation
    up = Roi.from_alignment_points(np.array([100.0, 200.0]), np.array([100.0, 100.0]))
    assert abs(up.angle) < 1e-9 and up.size == 2 * 100 * 1.25
    # body lying to the right (head at +x): the crop must rotate by +90 degrees
    lying = Roi.from_alignment_points(np.array([100.0, 200.0]), np.array([200.0, 200.0]))
    assert np.isclose(lying.angle, np.pi / 2)
    # the scale point maps to the top centre of the crop
    top = lying.crop_matrix(256) @ np.array([200.0, 200.0, 1.0])
    assert np.allclose(top, [128, 128 - 256 / 2.5])
