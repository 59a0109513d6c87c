"""Read the 35 mm-equivalent focal length (EXIF tag FocalLengthIn35mmFilm) from a JPEG file."""

from __future__ import annotations

import struct
from pathlib import Path

from posecam.errors import warn

EXIF_IFD_POINTER = 0x8769
FOCAL_LENGTH_35MM = 0xA405
SHORT = 3
# Plausible 35 mm-equivalent focal lengths: a fisheye to a long telephoto; 0 means "unknown".
FOCAL_RANGE_MM = (8, 1200)


def _ifd_entries(tiff: bytes, offset: int, endian: str) -> dict[int, tuple[int, int, bytes]]:
    """Entries of one IFD: tag -> (type, count, 4-byte value field)."""
    (count,) = struct.unpack_from(endian + "H", tiff, offset)
    entries = {}
    for i in range(count):
        tag, typ, n = struct.unpack_from(endian + "HHI", tiff, offset + 2 + 12 * i)
        entries[tag] = (typ, n, tiff[offset + 10 + 12 * i: offset + 14 + 12 * i])
    return entries


def _tiff_block(data: bytes) -> bytes | None:
    """The TIFF block of the first APP1 Exif segment of a JPEG, if any."""
    if data[:2] != b"\xff\xd8":
        return None
    pos = 2
    while pos + 4 <= len(data) and data[pos] == 0xFF:
        marker = data[pos + 1]
        (length,) = struct.unpack_from(">H", data, pos + 2)
        if marker == 0xE1 and data[pos + 4: pos + 10] == b"Exif\x00\x00":
            return data[pos + 10: pos + 2 + length]
        if marker == 0xDA:  # start of scan: no more metadata
            return None
        pos += 2 + length
    return None


def focal_length_35mm(path: str | Path) -> float | None:
    """FocalLengthIn35mmFilm in mm, or None when the file has no such tag (or is not a JPEG);
    a tag of the wrong type or outside FOCAL_RANGE_MM is ignored with a warning."""
    try:
        with open(path, "rb") as f:
            data = f.read(1 << 17)  # EXIF lives in the first 64 KiB segment
        tiff = _tiff_block(data)
        if not tiff or tiff[:2] not in (b"II", b"MM"):
            return None
        endian = "<" if tiff[:2] == b"II" else ">"
        (ifd0,) = struct.unpack_from(endian + "I", tiff, 4)
        pointer = _ifd_entries(tiff, ifd0, endian).get(EXIF_IFD_POINTER)
        if pointer is None:
            return None
        (exif_ifd,) = struct.unpack_from(endian + "I", pointer[2])
        entry = _ifd_entries(tiff, exif_ifd, endian).get(FOCAL_LENGTH_35MM)
        if entry is None:
            return None
    except (OSError, struct.error):
        return None
    typ, count, field = entry
    if typ != SHORT or count < 1:
        warn(f"{path}: EXIF FocalLengthIn35mmFilm has type {typ}, not SHORT; ignored")
        return None
    (value,) = struct.unpack_from(endian + "H", field)
    if value == 0:   # the standard's "unknown"
        return None
    if not FOCAL_RANGE_MM[0] <= value <= FOCAL_RANGE_MM[1]:
        warn(f"{path}: EXIF FocalLengthIn35mmFilm of {value} mm is outside {FOCAL_RANGE_MM[0]}.."
             f"{FOCAL_RANGE_MM[1]} mm; ignored")
        return None
    return float(value)
