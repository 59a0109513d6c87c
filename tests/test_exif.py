import struct

import cv2
import numpy as np
import pytest

from posecam.errors import PosecamWarning
from posecam.io.exif import focal_length_35mm


def _exif_segment(focal35: int, endian: str, typ: int = 3) -> bytes:
    """A minimal APP1 Exif segment: IFD0 with an Exif pointer, Exif IFD with FocalLengthIn35mmFilm."""
    e = "<" if endian == "II" else ">"
    tiff = endian.encode() + struct.pack(e + "HI", 42, 8)
    ifd0 = struct.pack(e + "H", 1) + struct.pack(e + "HHII", 0x8769, 4, 1, 26) + struct.pack(e + "I", 0)
    exif_ifd = (struct.pack(e + "H", 1) + struct.pack(e + "HHI", 0xA405, typ, 1)
                + struct.pack(e + "HH", focal35, 0) + struct.pack(e + "I", 0))
    body = b"Exif\x00\x00" + tiff + ifd0 + exif_ifd
    return b"\xff\xe1" + struct.pack(">H", len(body) + 2) + body


@pytest.mark.parametrize("endian", ["II", "MM"])
def test_reads_focal_length_in_35mm_film(tmp_path, endian):
    ok, jpg = cv2.imencode(".jpg", np.full((32, 48, 3), 128, np.uint8))
    data = jpg.tobytes()
    path = tmp_path / "photo.jpg"
    path.write_bytes(data[:2] + _exif_segment(26, endian) + data[2:])
    assert focal_length_35mm(path) == 26.0
    assert cv2.imread(str(path)) is not None          # still a valid JPEG


def test_no_exif_gives_none(tmp_path):
    ok, png = cv2.imencode(".png", np.zeros((8, 8, 3), np.uint8))
    (tmp_path / "a.png").write_bytes(png.tobytes())
    (tmp_path / "b.jpg").write_bytes(cv2.imencode(".jpg", np.zeros((8, 8, 3), np.uint8))[1].tobytes())
    assert focal_length_35mm(tmp_path / "a.png") is None
    assert focal_length_35mm(tmp_path / "b.jpg") is None


@pytest.mark.parametrize("focal35, typ, words", [(1, 3, "outside 8..1200"), (65535, 3, "outside 8..1200"),
                                                 (26, 4, "not SHORT"), (26, 2, "not SHORT")])
def test_implausible_or_mistyped_tag_is_ignored_with_a_warning(tmp_path, focal35, typ, words):
    data = cv2.imencode(".jpg", np.full((32, 48, 3), 128, np.uint8))[1].tobytes()
    path = tmp_path / "photo.jpg"
    path.write_bytes(data[:2] + _exif_segment(focal35, "II", typ) + data[2:])
    with pytest.warns(PosecamWarning, match=words):
        assert focal_length_35mm(path) is None
