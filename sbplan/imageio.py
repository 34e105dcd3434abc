"""Reading images and writing files safely.

Every file sbplan writes goes through :func:`write_atomic`: it is written to a temporary file in
the same folder and renamed over the target, so a failed run never leaves a half-written file and
never destroys a good one.
"""

from __future__ import annotations

import json
import os
import struct
import tempfile
import zlib
from pathlib import Path
from typing import Any, Callable

import cv2
import numpy as np

from .errors import ImageError


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


def load_image(path: str | os.PathLike) -> np.ndarray:
    """Read an image file as 8-bit grayscale, shape (H, W). 16-bit files are scaled."""
    p = Path(path)
    if not p.exists():
        raise ImageError(f"{p}: no such file")
    if p.is_dir():
        raise ImageError(f"{p}: is a folder, not an image")
    data = np.fromfile(str(p), dtype=np.uint8)
    image = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
    if image is None:
        raise ImageError(f"{p}: not an image OpenCV can read")
    return as_gray(image, name=str(p))


def write_atomic(path: str | os.PathLike, write: Callable[[Any], None] | bytes | str, *, binary: bool = True) -> Path:
    """Write a file atomically. ``write`` is the content, or a function given the open file."""
    p = Path(path)
    folder = p.parent if str(p.parent) else Path(".")
    folder.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=folder)
    try:
        # mkstemp makes the file private (0600); a result file should be as readable as any other
        # (a replaced file keeps its mode)
        os.chmod(tmp, p.stat().st_mode & 0o7777 if p.exists() else 0o644)
        mode = "wb" if binary and not isinstance(write, str) else "w"
        with os.fdopen(fd, mode, **({} if "b" in mode else {"encoding": "utf-8"})) as fh:
            if callable(write):
                write(fh)
            else:
                fh.write(write)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, p)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    return p


def write_json(path: str | os.PathLike, obj: Any) -> Path:
    """Write ``obj`` as indented JSON, atomically."""
    text = json.dumps(obj, indent=2, default=json_default) + "\n"
    return write_atomic(path, text)


def write_image(path: str | os.PathLike, image: np.ndarray, *, text: dict[str, str] | None = None) -> Path:
    """Write an image (PNG, PGM, JPEG… by the file's ending) atomically.

    ``text``: keyword -> value pairs the file carries about itself (what :func:`image_text`
    reads): PNG ``tEXt`` chunks, or comment lines in a PGM/PPM header; other formats carry none.
    """
    p = Path(path)
    ext = p.suffix.lower() or ".png"
    ok, buf = cv2.imencode(ext, image)
    if not ok:
        raise ImageError(f"{p}: cannot encode an image as {ext}")
    data = buf.tobytes()
    if text:
        data = _with_text(data, ext, text)
    return write_atomic(p, data)


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
                key, _, value = head[i + 8:i + 8 + n].partition(b"\0")
                out[key.decode("latin-1")] = value.decode("latin-1")
            i += 12 + n
    elif head[:1] == b"P" and head[1:2] in b"123456":
        for line in head.split(b"\n")[1:8]:
            if line.startswith(b"#") and b":" in line:
                key, _, value = line[1:].decode("latin-1").partition(":")
                out[key.strip()] = value.strip()
    return out


def json_default(obj: Any) -> Any:
    """``json.dumps(default=...)`` for numpy values, arrays, paths and tuples."""
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, tuple):
        return list(obj)
    raise TypeError(f"not JSON serializable: {type(obj).__name__}")
