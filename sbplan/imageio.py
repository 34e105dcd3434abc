"""Reading images (validated, size-checked before decoding) and writing them.

Every file sbplan writes goes through :func:`sbplan.files.write_atomic` (re-exported here with
:func:`write_json`): it is written to a temporary file in the same folder and renamed over the
target, so a failed run never leaves a half-written file and never destroys a good one.
"""

from __future__ import annotations

import contextlib
import functools
import os
import stat
import struct
import sys
import tempfile
import threading
import zlib
from pathlib import Path
from typing import Any, Iterator

import cv2
import numpy as np

from . import limits
from .errors import ImageError, OutputError
from .files import json_default, write_atomic, write_json  # noqa: F401  (re-exported)

#: An image the pipeline takes: a path of an image file, or an array (H, W), (H, W, 3) or (H, W, 4)
#: (see :func:`as_gray`).
ImageInput = str | os.PathLike | np.ndarray


def as_gray(image: Any, *, name: str = "image") -> np.ndarray:
    """Validate an image array and return it as 8-bit grayscale.

    Parameters
    ----------
    image : array_like of shape (H, W), (H, W, 3) or (H, W, 4)
        uint8, uint16 (scaled to 8 bits by its full range 0..65535), bool, or float in [0, 1].
        Colour is taken as BGR(A), OpenCV's order, and converted to luminance.
    name : str
        How the image is called in error messages.

    Returns
    -------
    ndarray of shape (H, W), uint8, C-contiguous.
    """
    if not isinstance(image, np.ndarray):
        try:
            image = np.asarray(image)
        except Exception:
            raise ImageError(f"{name}: not an image array") from None
    if image.dtype == object or image.dtype.kind not in "buif":
        raise ImageError(f"{name}: not an image array (dtype {image.dtype})")
    if image.size == 0 or image.ndim < 2 or min(image.shape[:2]) == 0:
        raise ImageError(f"{name}: empty image (shape {image.shape})")
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[:, :, 0]
    if image.ndim == 3:
        if image.shape[2] not in (3, 4):
            raise ImageError(f"{name}: expected 1, 3 or 4 channels, got {image.shape[2]}")
    elif image.ndim != 2:
        raise ImageError(f"{name}: expected a 2-D grayscale or 3-D colour array, got shape {image.shape}")
    if image.dtype == np.bool_:
        image = image.astype(np.uint8) * 255
    elif image.dtype == np.uint16:
        image = (image.astype(np.uint32) * 255 + 32767) // 65535
        image = image.astype(np.uint8)
    elif image.dtype.kind == "f":
        if not np.isfinite(image).all():
            raise ImageError(f"{name}: contains NaN or infinite values")
        lo, hi = float(image.min()), float(image.max())
        if lo < 0.0 or hi > 1.0:
            raise ImageError(f"{name}: float images must lie in [0, 1], got [{lo:.3g}, {hi:.3g}]")
        image = np.round(image * 255).astype(np.uint8)
    elif image.dtype != np.uint8:
        raise ImageError(f"{name}: unsupported dtype {image.dtype}; use uint8, uint16, bool or float in [0, 1]")
    if image.ndim == 3:
        code = cv2.COLOR_BGR2GRAY if image.shape[2] == 3 else cv2.COLOR_BGRA2GRAY
        image = cv2.cvtColor(np.ascontiguousarray(image), code)
    return np.ascontiguousarray(image)


def halve(image: np.ndarray) -> np.ndarray:
    """``image`` (H, W) made half as large by averaging 2 x 2 blocks (rounded): the values of
    ``cv2.resize(image, (W // 2, H // 2), interpolation=cv2.INTER_AREA)``.

    For uint8 with even sides, a compiled loop (:func:`sbplan._kernels.halve_u8`) computes OpenCV's
    rounded block means, reading the row pairs in order: detection halves every frame, and a
    camera's frame is not in the cache yet (169 -> 111 us at 1280 x 960 on a frame read cold;
    OpenCV's exact bilinear resize, which gives the same values, was the faster of its own). Anything
    else takes ``INTER_AREA`` itself.
    """
    h, w = image.shape[:2]
    if image.dtype == np.uint8 and image.ndim == 2 and h % 2 == 0 and w % 2 == 0 and h and w \
            and image.strides[1] == 1:
        return _compiled().halve_u8(image, np.empty((h // 2, w // 2), np.uint8))
    return cv2.resize(image, (w // 2, h // 2), interpolation=cv2.INTER_AREA)


@functools.cache
def _compiled():
    """The compiled kernels, imported on first use (numba takes a moment; see ``sbplan._kernels``)."""
    from . import _kernels
    return _kernels


def image_size(head: bytes) -> tuple[int, int] | None:
    """Width and height of an encoded image from its header, without decoding it.

    Reads the headers of every format OpenCV decodes here: PNG, JPEG, PNM (PBM/PGM/PPM/PAM/PFM),
    BMP, TIFF and BigTIFF, WebP, GIF, JPEG 2000 (JP2 and raw codestream), AVIF, Radiance HDR and
    Sun raster. None for other formats and for headers it cannot make sense of;
    :func:`read_image` refuses those rather than decode them unchecked.

    Parameters
    ----------
    head : bytes
        The file's first bytes (a JPEG's size may come after its metadata: give the whole file).
    """
    try:
        return _header_size(head)
    except (struct.error, IndexError, KeyError, ValueError):
        return None


def _header_size(b: bytes) -> tuple[int, int] | None:
    if b[:8] == b"\x89PNG\r\n\x1a\n" and b[12:16] == b"IHDR":
        return struct.unpack(">II", b[16:24])
    if b[:2] == b"\xff\xd8":
        i = 2
        while i + 9 < len(b):
            if b[i] != 0xFF:
                return None
            marker = b[i + 1]
            if marker == 0xFF:  # fill byte
                i += 1
                continue
            if marker in (0xD8, 0x01) or 0xD0 <= marker <= 0xD7:
                i += 2
                continue
            (length,) = struct.unpack(">H", b[i + 2:i + 4])
            if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
                h, w = struct.unpack(">HH", b[i + 5:i + 9])
                return w, h
            i += 2 + length
        return None
    if b[:1] == b"P" and b[1:2] in b"123456" and len(b) > 2:
        fields: list[int] = []
        for line in b[2:4096].split(b"\n"):
            line = line.split(b"#", 1)[0]
            fields += [int(t) for t in line.split()]
            if len(fields) >= 2:
                return fields[0], fields[1]
        return None
    if b[:2] == b"BM":
        w, h = struct.unpack("<ii", b[18:26])
        return abs(w), abs(h)
    if b[:4] in (b"II*\x00", b"MM\x00*"):
        e = "<" if b[:2] == b"II" else ">"
        (ifd,) = struct.unpack(e + "I", b[4:8])
        (n,) = struct.unpack(e + "H", b[ifd:ifd + 2])
        size = {}
        for k in range(n):
            tag, typ, _count = struct.unpack(e + "HHI", b[ifd + 2 + 12 * k:ifd + 10 + 12 * k])
            if tag in (256, 257):
                at = ifd + 10 + 12 * k
                size[tag] = struct.unpack(e + ("H" if typ == 3 else "I"), b[at:at + (2 if typ == 3 else 4)])[0]
        return (size[256], size[257]) if len(size) == 2 else None
    if b[:2] in (b"PF", b"Pf") and b[2:3] in b" \t\r\n":  # PFM: "PF\nW H\nscale\n"
        w, h = (int(t) for t in b[2:256].split()[:2])
        return w, h
    if b[:3] == b"P7\n":  # PAM: "WIDTH W" and "HEIGHT H" lines
        tags = dict(line.split()[:2] for line in b[3:4096].split(b"ENDHDR")[0].split(b"\n")
                    if len(line.split()) >= 2)
        return int(tags[b"WIDTH"]), int(tags[b"HEIGHT"])
    if b[:4] in (b"II+\x00", b"MM\x00+"):  # BigTIFF: 8-byte offsets, 20-byte IFD entries
        e = "<" if b[:2] == b"II" else ">"
        (ifd,) = struct.unpack(e + "Q", b[8:16])
        (n,) = struct.unpack(e + "Q", b[ifd:ifd + 8])
        size = {}
        for k in range(min(n, 4096)):
            at = ifd + 8 + 20 * k
            tag, typ = struct.unpack(e + "HH", b[at:at + 4])
            if tag in (256, 257):
                fmt = {3: "H", 4: "I", 16: "Q"}[typ]
                size[tag] = struct.unpack(e + fmt, b[at + 12:at + 12 + struct.calcsize(fmt)])[0]
        return (size[256], size[257]) if len(size) == 2 else None
    if b[:6] in (b"GIF87a", b"GIF89a"):
        return struct.unpack("<HH", b[6:10])
    if b[:4] == b"\x59\xa6\x6a\x95":  # Sun raster
        return struct.unpack(">II", b[4:12])
    if b[:2] == b"#?":  # Radiance HDR: header lines, an empty line, then "-Y H +X W" (any order)
        _, _, rest = b[:65536].partition(b"\n\n")
        tokens = rest.split(b"\n", 1)[0].split()
        axes = {tokens[k][1:2]: int(tokens[k + 1]) for k in (0, 2)}
        return axes[b"X"], axes[b"Y"]
    if b[:4] == b"\xff\x4f\xff\x51":  # JPEG 2000 codestream: SIZ gives the grid minus its offset
        xs, ys, xo, yo = struct.unpack(">IIII", b[8:24])
        return xs - xo, ys - yo
    if b[4:8] == b"jP  ":  # JP2: boxes; the image header box lies in the jp2h box
        i = 0
        while i + 8 <= len(b):
            length, kind = struct.unpack(">I4s", b[i:i + 8])
            if kind == b"ihdr":
                h, w = struct.unpack(">II", b[i + 8:i + 16])
                return w, h
            if kind == b"jp2h":
                i += 8
                continue
            if length == 1:
                (length,) = struct.unpack(">Q", b[i + 8:i + 16])
            if length < 8:
                return None
            i += length
        return None
    if b[4:8] == b"ftyp" and b[8:12] in (b"avif", b"avis", b"heic", b"heix", b"mif1", b"msf1"):
        # HEIF/AVIF: every item's 'ispe' property box; the largest bounds what is decoded
        sizes = []
        i = b.find(b"ispe", 0, 1 << 20)
        while i >= 0:
            sizes.append(struct.unpack(">II", b[i + 8:i + 16]))
            i = b.find(b"ispe", i + 4, 1 << 20)
        return max(sizes, key=lambda s: s[0] * s[1]) if sizes else None
    if b[:4] == b"RIFF" and b[8:12] == b"WEBP":
        chunk = b[12:16]
        if chunk == b"VP8 ":
            w, h = struct.unpack("<HH", b[26:30])
            return w & 0x3FFF, h & 0x3FFF
        if chunk == b"VP8L":
            v = int.from_bytes(b[21:25], "little")
            return (v & 0x3FFF) + 1, ((v >> 14) & 0x3FFF) + 1
        if chunk == b"VP8X":
            return int.from_bytes(b[24:27], "little") + 1, int.from_bytes(b[27:30], "little") + 1
    return None


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_quiet_lock = threading.Lock()
_quiet_users = 0
_quiet_saved: int | None = None


@contextlib.contextmanager
def _opencv_silent() -> Iterator[None]:
    """OpenCV's own log lines (``[ WARN:0@...] ... PNG input buffer is incomplete``) off while
    inside; our error says what went wrong instead. Counted, so that threads decoding at the
    same time restore the level only when the last one leaves."""
    global _quiet_users, _quiet_saved
    log = cv2.utils.logging
    with _quiet_lock:
        if _quiet_users == 0:
            _quiet_saved = log.getLogLevel()
            log.setLogLevel(log.LOG_LEVEL_SILENT)
        _quiet_users += 1
    try:
        yield
    finally:
        with _quiet_lock:
            _quiet_users -= 1
            if _quiet_users == 0 and _quiet_saved is not None:
                log.setLogLevel(_quiet_saved)


def _damage(data: bytes) -> str | None:
    """Why a PNG or JPEG file is damaged (truncated, a chunk's checksum wrong), or None.

    Checked before decoding because libpng and libjpeg print their own complaints to the
    process's stderr (``libpng error: ...``), which no log level silences."""
    if data.startswith(_PNG_SIGNATURE):
        pos = len(_PNG_SIGNATURE)
        while True:
            if pos + 8 > len(data):
                return "truncated PNG (no IEND chunk)"
            length, kind = struct.unpack(">I4s", data[pos:pos + 8])
            end = pos + 12 + length
            if end > len(data):
                return f"truncated PNG (its {kind.decode('latin-1')} chunk is cut off)"
            crc = struct.unpack(">I", data[end - 4:end])[0]
            if zlib.crc32(data[pos + 4:end - 4]) != crc:
                return f"damaged PNG (the checksum of its {kind.decode('latin-1')} chunk is wrong)"
            if kind == b"IEND":
                return None
            pos = end
    if data.startswith(b"\xff\xd8") and not data.rstrip(b"\x00").endswith(b"\xff\xd9"):
        return "truncated JPEG (no end-of-image marker)"
    return None


def load_image(path: str | os.PathLike) -> np.ndarray:
    """Read an image file as 8-bit grayscale, shape (H, W). 16-bit files are scaled.

    The image's size is read from its header and checked against the ``image_pixels`` limit
    (:mod:`sbplan.limits`) before it is decoded (:func:`read_image`).
    """
    return as_gray(read_image(path), name=str(Path(path)))


def read_image(path: str | os.PathLike) -> np.ndarray:
    """Read an image file as it is stored: (H, W) grey or (H, W, C) BGR(A), 8 or 16 bits (a nav2
    map's alpha channel and bit depth matter). Checked as :func:`load_image` checks it.

    A damaged PNG or JPEG (cut short, a chunk's checksum wrong) is refused saying so, and nothing
    else is printed: OpenCV's and the PNG and JPEG libraries' own messages are kept off stderr.

    Raises
    ------
    ImageError
        No such file, not a regular file, damaged, or not an image OpenCV can read.
    LimitError
        More pixels than the limit.
    """
    p = Path(path)
    try:
        st = p.stat()
    except FileNotFoundError:
        raise ImageError(f"{p}: no such file") from None
    except OSError as exc:
        raise ImageError(f"{p}: cannot be read ({exc.strerror})") from None
    if stat.S_ISDIR(st.st_mode):
        raise ImageError(f"{p}: is a folder, not an image")
    if not stat.S_ISREG(st.st_mode):
        raise ImageError(f"{p}: is not a regular file (a device, FIFO or socket); give an image file")
    top = limits.limit("image_pixels")
    # an encoded image is never much larger than its pixels (16-bit RGBA, uncompressed)
    limits.check("image_pixels", (st.st_size - 65536) / 8, f"{p}: a {st.st_size:,}-byte file")
    try:
        data = np.fromfile(str(p), dtype=np.uint8)
    except OSError as exc:
        raise ImageError(f"{p}: cannot be read ({exc.strerror})") from None
    if not data.size:
        raise ImageError(f"{p}: not an image OpenCV can read (an empty file)")
    raw = data.tobytes()
    size = image_size(raw)
    if size is None:
        # decoding first and checking after is what a decompression bomb needs: a file whose
        # size no header gives is not decoded at all
        raise ImageError(f"{p}: not an image OpenCV can read, or a format whose size sbplan cannot read "
                         "before decoding it (PNG, JPEG, TIFF, BMP, PNM, WebP, GIF, JPEG 2000, AVIF, HDR and "
                         "Sun raster are read)")
    w, h = size
    if w <= 0 or h <= 0:
        raise ImageError(f"{p}: not an image OpenCV can read (its header says {w} x {h} pixels)")
    limits.check("image_pixels", w * h, f"{p}: {w} x {h} pixels", "give a smaller image")
    why = _damage(raw)
    if why is not None:
        raise ImageError(f"{p}: not an image OpenCV can read: {why}")
    with _opencv_silent():
        image, said = _decode(data)
    if image is None:
        raise ImageError(f"{p}: not an image OpenCV can read" + (f" ({said[-1]})" if said else ""))
    h, w = image.shape[:2]
    if h * w > top:  # a header that understated the size (a GIF frame larger than its screen)
        limits.check("image_pixels", h * w, f"{p}: decoded to {w} x {h} pixels", "give a smaller image")
    if image.size == 0:
        raise ImageError(f"{p}: empty image")
    return image


def _decode(data: np.ndarray) -> tuple[np.ndarray | None, list[str]]:
    """``cv2.imdecode`` with what libpng says about a damaged file taken off the process's stderr.

    libpng prints "libpng error: ..." on file descriptor 2 itself, below Python: a command would
    print two lines for one damaged file. Its lines are returned, for the error message; anything
    else written to descriptor 2 meanwhile (another thread) is passed on.
    """
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError, AttributeError):  # no descriptor 2 (a daemon): nothing to keep clean
        saved = None
    if saved is None:
        try:
            return cv2.imdecode(data, cv2.IMREAD_UNCHANGED), []
        except cv2.error:
            return None, []
    with tempfile.TemporaryFile() as caught:
        os.dup2(caught.fileno(), 2)
        try:
            image = cv2.imdecode(data, cv2.IMREAD_UNCHANGED)
        except cv2.error:
            image = None
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        caught.seek(0)
        lines = caught.read().decode("utf-8", "replace").splitlines(keepends=True)
    said = [line.strip() for line in lines if line.startswith("libpng ")]
    others = "".join(line for line in lines if not line.startswith("libpng "))
    if others:
        os.write(2, others.encode("utf-8"))
    return image, said


def encode_image(path: str | os.PathLike, image: np.ndarray, *, text: dict[str, str] | None = None) -> bytes:
    """``image`` encoded in the format the file name's ending names (PNG, PGM, JPEG, ...).

    ``text``: keyword -> value pairs the file carries about itself (what :func:`image_text`
    reads): PNG ``tEXt`` chunks, or comment lines in a PGM/PPM header; other formats carry none.

    Raises
    ------
    OutputError
        No encoder for that ending, or the image cannot be encoded in that format.
    """
    p = Path(path)
    ext = p.suffix.lower() or ".png"
    try:
        ok, buf = cv2.imencode(ext, image)
    except cv2.error:
        ok = False
    if not ok:
        raise OutputError(f"{p}: cannot write images ending in {ext!r}; use .png, .pgm, .jpg, .bmp or .tif")
    data = buf.tobytes()
    return _with_text(data, ext, text) if text else data


def write_image(path: str | os.PathLike, image: np.ndarray, *, text: dict[str, str] | None = None) -> Path:
    """Write an image (PNG, PGM, JPEG… by the file's ending) atomically, with ``text`` as
    :func:`encode_image` writes it."""
    return write_atomic(path, encode_image(path, image, text=text))


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _with_text(data: bytes, ext: str, text: dict[str, str]) -> bytes:
    if ext == ".png" and data.startswith(_PNG_SIGNATURE):
        chunks = b""
        for key, value in text.items():
            body = key.encode("latin-1") + b"\0" + value.encode("latin-1", "replace")
            chunks += (struct.pack(">I", len(body)) + b"tEXt" + body
                       + struct.pack(">I", zlib.crc32(b"tEXt" + body) & 0xFFFFFFFF))
        ihdr_end = 8 + 8 + struct.unpack(">I", data[8:12])[0] + 4  # signature, IHDR's length+type, data, CRC
        return data[:ihdr_end] + chunks + data[ihdr_end:]
    if ext in (".pgm", ".ppm", ".pnm", ".pbm") and data[:1] == b"P":
        magic, rest = data.split(b"\n", 1)
        comments = b"".join(f"# {k}: {v}\n".encode("latin-1", "replace") for k, v in text.items())
        return magic + b"\n" + comments + rest
    return data


def image_text(path: str | os.PathLike) -> dict[str, str]:
    """What an image file says about itself: a PNG's ``tEXt`` chunks, or ``# key: value``
    comment lines of a PGM/PPM header (as :func:`write_image` writes them). Empty for other
    files, or when the file cannot be read."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(1 << 16)
    except OSError:
        return {}
    out: dict[str, str] = {}
    if head.startswith(_PNG_SIGNATURE):
        i = 8
        while i + 8 <= len(head):
            n = struct.unpack(">I", head[i:i + 4])[0]
            kind = head[i + 4:i + 8]
            if kind in (b"IDAT", b"IEND") or i + 8 + n > len(head):
                break
            if kind == b"tEXt":
                raw_key, _, raw_value = head[i + 8:i + 8 + n].partition(b"\0")
                out[raw_key.decode("latin-1")] = raw_value.decode("latin-1")
            i += 12 + n
    elif head[:1] == b"P" and head[1:2] in b"123456":
        for line in head.split(b"\n")[1:8]:
            if line.startswith(b"#") and b":" in line:
                key, _, value = line[1:].decode("latin-1").partition(":")
                out[key.strip()] = value.strip()
    return out
