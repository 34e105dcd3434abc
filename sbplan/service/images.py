"""Frames posted to the service: their size read from the file header, before anything is decoded.

A 40-byte PNG can declare 100 000 x 100 000 pixels; decoding it would allocate 10 GB. So the
service reads the width and height from the PNG header (IHDR) or the JPEG frame header (SOFn) and
refuses the image before OpenCV sees it when it is larger than the limit or than the calibration.
"""

from __future__ import annotations

import struct

import cv2
import numpy as np

from ..errors import ImageError
from ..imageio import as_gray
from .errors import PayloadTooLargeError, ServiceError

_PNG = b"\x89PNG\r\n\x1a\n"
#: JPEG start-of-frame markers (baseline, progressive, lossless, ...): all but DHT (C4), JPG (C8)
#: and DAC (CC), which share the range.
_SOF = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}
#: Markers without a length field.
_STANDALONE = frozenset(range(0xD0, 0xD8)) | {0x01, 0xD8}


def image_header(data: bytes) -> tuple[str, int, int]:
    """The format and size of a PNG or JPEG file, from its header only.

    Parameters
    ----------
    data : bytes
        The file's content (only the header is read).

    Returns
    -------
    (kind, width, height) : ("png" | "jpeg", int, int)

    Raises
    ------
    ImageError
        Not a PNG or JPEG file, or a header without a size.
    """
    if data[:8] == _PNG:
        if len(data) < 24 or data[12:16] != b"IHDR":
            raise ImageError("image: a PNG file without its IHDR header")
        width, height = struct.unpack(">II", data[16:24])
        return "png", width, height
    if data[:2] == b"\xff\xd8":
        return ("jpeg", *_jpeg_size(data))
    raise ImageError("image: not a PNG or JPEG file")


def _jpeg_size(data: bytes) -> tuple[int, int]:
    i, n = 2, len(data)
    while i + 4 <= n:
        if data[i] != 0xFF:
            raise ImageError("image: a JPEG file with a broken marker sequence")
        marker = data[i + 1]
        if marker == 0xFF:  # fill byte before a marker
            i += 1
            continue
        if marker in _STANDALONE:
            i += 2
            continue
        if marker == 0xD9:  # end of image before any frame header
            break
        (length,) = struct.unpack(">H", data[i + 2:i + 4])
        if marker in _SOF:
            if i + 9 > n:
                break
            height, width = struct.unpack(">HH", data[i + 5:i + 9])
            return width, height
        i += 2 + length
    raise ImageError("image: a JPEG file without a frame header")


def check_size(data: bytes, *, max_pixels: int, expected: tuple[int, int] | None = None) -> tuple[int, int]:
    """Read the header and check the size: ``(width, height)``.

    Raises ImageError for a file that is not a PNG or JPEG, PayloadTooLargeError above
    ``max_pixels``, a ServiceError ``wrong-image-size`` when it differs from ``expected``
    ``(height, width)`` (the calibration's).
    """
    _, width, height = image_header(data)
    if width == 0 or height == 0:
        raise ImageError(f"image: empty ({width} x {height} pixels)")
    if width * height > max_pixels:
        raise PayloadTooLargeError(f"image: {width} x {height} pixels is above the limit of {max_pixels} pixels",
                                   code="image-too-large")
    if expected is not None and (height, width) != tuple(expected):
        raise ServiceError(f"image: {width} x {height} pixels, but the calibration is {expected[1]} x {expected[0]}",
                           code="wrong-image-size", status=422)
    return width, height


def decode(data: bytes, size: tuple[int, int]) -> np.ndarray:
    """Decode a checked PNG or JPEG into grayscale (H, W) uint8; ``size`` is its header's
    ``(width, height)``, which the decoded image must have."""
    image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise ImageError("image: the file is damaged or truncated (OpenCV cannot decode it)")
    if (image.shape[1], image.shape[0]) != tuple(size):
        raise ImageError(f"image: decodes to {image.shape[1]} x {image.shape[0]} pixels, its header says "
                         f"{size[0]} x {size[1]}")
    return as_gray(image)
