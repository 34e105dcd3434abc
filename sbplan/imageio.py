"""Reading images and writing files safely.

Every file sbplan writes goes through :func:`write_atomic`: it is written to a temporary file in
the same folder and renamed over the target, so a failed run never leaves a half-written file and
never destroys a good one.
"""

from __future__ import annotations

import contextlib
import json
import os
import struct
import tempfile
import threading
import zlib
from pathlib import Path
from typing import Any, Callable, Iterator

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

    A damaged file raises :class:`~sbplan.errors.ImageError` saying so, and nothing else is
    printed: OpenCV's and the PNG and JPEG libraries' own messages are kept off stderr."""
    p = Path(path)
    if not p.exists():
        raise ImageError(f"{p}: no such file")
    if p.is_dir():
        raise ImageError(f"{p}: is a folder, not an image")
    data = np.fromfile(str(p), dtype=np.uint8)
    why = _damage(data.tobytes())
    if why is not None:
        raise ImageError(f"{p}: not an image OpenCV can read: {why}")
    with _opencv_silent():
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


def write_image(path: str | os.PathLike, image: np.ndarray) -> Path:
    """Write an image (PNG, PGM, JPEG… by the file's ending) atomically."""
    p = Path(path)
    ext = p.suffix.lower() or ".png"
    ok, buf = cv2.imencode(ext, image)
    if not ok:
        raise ImageError(f"{p}: cannot encode an image as {ext}")
    return write_atomic(p, buf.tobytes())


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
