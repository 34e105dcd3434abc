"""Printable floor tiles: one reference symbol centred on a square of the grid pitch, with crop marks.

Laying the tiles edge to edge puts the symbols' centres of area on a regular grid with the tile side
as its pitch, which is what calibration fits. The symbol is placed by its **centre of area** (paper
equation 1), not its bounding box, because that is the point detection measures.

Page layout (all lengths in millimetres, y down from the page's top-left corner): the tile (the
trim box) sits inside a margin of ``bleed`` on every side; crop marks are short lines in that
margin on the extension of the tile's edges, plus a tick at the middle of each side to align
neighbouring tiles; a one-line label names the symbol and the sizes. With ``crop_marks=False`` the
page is the tile itself.

Formats: SVG (mm units, even-odd fill), PDF (a hand-written single-page vector PDF: MediaBox and
TrimBox in points, the symbol as one even-odd filled path, Helvetica label), PNG (at a stated dpi,
antialiased, with the dpi recorded in a pHYs chunk).
"""

from __future__ import annotations

import math
import re
import struct
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ..errors import InputError
from ..imageio import write_atomic
from .raster import coverage, place, symbol_rings

__all__ = ["FORMATS", "Tile", "parse_length", "tile_pdf", "tile_png", "tile_svg", "write_tile"]

FORMATS = ("svg", "pdf", "png")
_UNITS_MM = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4, "pt": 25.4 / 72}
_PT_PER_MM = 72 / 25.4


def parse_length(text: str | float, *, name: str = "size") -> float:
    """A length in millimetres from ``"200mm"``, ``"20cm"``, ``"0.2m"``, ``"8in"``, ``"567pt"`` or a
    bare number (millimetres)."""
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        value, unit = float(text), "mm"
    else:
        m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*([a-zA-Z]*)\s*", str(text))
        if not m or m.group(2).lower() not in ("", *_UNITS_MM):
            raise InputError(f"{name}: expected a length like 200mm, 20cm, 0.2m or 8in, got {text!r}")
        value, unit = float(m.group(1)), (m.group(2).lower() or "mm")
    mm = value * _UNITS_MM[unit]
    if not (math.isfinite(mm) and mm > 0):
        raise InputError(f"{name}: must be a positive length, got {text!r}")
    return mm


@dataclass(frozen=True)
class Tile:
    """The geometry of one printable tile, in millimetres, y down from the page's top-left.

    Attributes
    ----------
    name : str
        The symbol's name (for the label).
    size : float
        Tile side = grid pitch.
    symbol_size : float
        Side of the symbol's unit box.
    bleed : float
        Margin around the tile holding the crop marks (0 without crop marks).
    rings : list of ndarray (N, 2)
        The symbol's ``[outline, *holes]`` on the page ``(x, y)``; its centre of area is the tile's
        centre.
    marks : list of ((x0, y0), (x1, y1))
        Crop-mark and centre-tick segments.
    label : str
        One line of text for the bottom margin ('' without crop marks).
    """

    name: str
    size: float
    symbol_size: float
    bleed: float
    rings: list
    marks: list
    label: str
    mark_width: float = 0.25

    @property
    def page(self) -> float:
        """Side of the (square) page."""
        return self.size + 2 * self.bleed

    @classmethod
    def build(cls, symbol: Any, *, size: float | str = 200.0, symbol_fraction: float = 0.45,
              symbol_size: float | str | None = None, angle: float = 0.0, crop_marks: bool = True,
              bleed: float | str = 12.0) -> "Tile":
        """Lay out a tile.

        Parameters
        ----------
        symbol : str or polygon(s)
            A registered symbol name, or ``[outline, *holes]`` in a unit box (y down).
        size : float or str
            Tile side (the grid pitch): millimetres, or a string with a unit (``"200mm"``).
        symbol_fraction : float
            The symbol's unit box as a fraction of the tile (the renderer's default is 0.45).
        symbol_size : float or str, optional
            The unit box's side as a length; overrides ``symbol_fraction``.
        angle : float
            Rotation of the symbol in degrees, counter-clockwise as displayed.
        crop_marks : bool
            Add a margin with crop marks, centre ticks and a label.
        bleed : float or str
            Width of that margin (at least 6 mm).
        """
        size_mm = parse_length(size, name="size")
        if symbol_size is not None:
            sym_mm = parse_length(symbol_size, name="symbol_size")
        else:
            if isinstance(symbol_fraction, bool) or not isinstance(symbol_fraction, (int, float)) \
                    or not 0 < symbol_fraction < 1:
                raise InputError(f"symbol_fraction: expected a fraction in (0, 1), got {symbol_fraction!r}")
            sym_mm = symbol_fraction * size_mm
        if not isinstance(angle, (int, float)) or isinstance(angle, bool) or not math.isfinite(angle):
            raise InputError(f"angle: expected a number of degrees, got {angle!r}")
        bleed_mm = parse_length(bleed, name="bleed") if crop_marks else 0.0
        if crop_marks and bleed_mm < 6:
            raise InputError(f"bleed: crop marks need a margin of at least 6 mm, got {bleed_mm:.3g} mm")
        rings = symbol_rings(symbol)
        centre = (bleed_mm + size_mm / 2, bleed_mm + size_mm / 2)
        placed = place(rings, size=sym_mm, angle=angle, centre=centre)
        pts = np.vstack(placed)
        lo, hi = bleed_mm, bleed_mm + size_mm
        if pts.min() < lo or pts.max() > hi:
            raise InputError(f"symbol_size: a {sym_mm:.4g} mm symbol does not fit a {size_mm:.4g} mm tile "
                             f"when centred on its centre of area; use a smaller symbol_fraction")
        name = symbol if isinstance(symbol, str) else "custom"
        marks: list = []
        label = ""
        if crop_marks:
            gap, length = 2.0, min(8.0, bleed_mm - 3.0)
            for x in (lo, hi):
                for y in (lo, hi):
                    sx = -1 if x == lo else 1
                    sy = -1 if y == lo else 1
                    marks.append(((x + sx * gap, y), (x + sx * (gap + length), y)))
                    marks.append(((x, y + sy * gap), (x, y + sy * (gap + length))))
            mid = bleed_mm + size_mm / 2
            tick = min(4.0, length)
            marks += [((mid, lo - gap), (mid, lo - gap - tick)), ((mid, hi + gap), (mid, hi + gap + tick)),
                      ((lo - gap, mid), (lo - gap - tick, mid)), ((hi + gap, mid), (hi + gap + tick, mid))]
            label = (f"sbplan tile: {name}, pitch {size_mm:g} mm, symbol {sym_mm:.4g} mm"
                     f"{f', rotated {angle:g} deg' if angle else ''}; cut on the marks")
        return cls(name, size_mm, sym_mm, bleed_mm, placed, marks, label)


def _fmt(v: float) -> str:
    return f"{v:.4f}".rstrip("0").rstrip(".")


def tile_svg(tile: Tile) -> str:
    """The tile as an SVG document in millimetres (``width``/``height`` in mm, viewBox in mm)."""
    p = _fmt(tile.page)
    d = " ".join("M " + " L ".join(f"{_fmt(x)} {_fmt(y)}" for x, y in r) + " Z" for r in tile.rings)
    out = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<svg xmlns="http://www.w3.org/2000/svg" version="1.1" width="{p}mm" height="{p}mm" viewBox="0 0 {p} {p}">',
        f"<title>{_xml(tile.label or tile.name)}</title>",
        f'<rect x="0" y="0" width="{p}" height="{p}" fill="#ffffff"/>',
        f'<path id="symbol" d="{d}" fill="#000000" fill-rule="evenodd" stroke="none"/>',
    ]
    if tile.marks:
        md = " ".join(f"M {_fmt(a[0])} {_fmt(a[1])} L {_fmt(b[0])} {_fmt(b[1])}" for a, b in tile.marks)
        out.append(f'<path id="crop-marks" d="{md}" fill="none" stroke="#000000" '
                   f'stroke-width="{_fmt(tile.mark_width)}"/>')
        out.append(f'<text x="{_fmt(tile.bleed + 4)}" y="{_fmt(tile.page - 2.5)}" '
                   f'font-family="Helvetica, Arial, sans-serif" font-size="2.8" fill="#000000">{_xml(tile.label)}</text>')
    out.append("</svg>")
    return "\n".join(out) + "\n"


def _xml(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;").replace('"', "&quot;")


def _pdf_text(text: str) -> str:
    return text.encode("latin-1", "replace").decode("latin-1").replace("\\", "\\\\").replace("(", "\\(").replace(")", "\\)")


def tile_pdf(tile: Tile) -> bytes:
    """The tile as a one-page vector PDF (PDF 1.4). MediaBox is the page and TrimBox the tile, in
    points (1 pt = 1/72 in); the symbol is one path filled with the even-odd rule (``f*``)."""
    k = _PT_PER_MM
    page = tile.page * k

    def pt(x: float, y: float) -> str:
        return f"{_fmt(x * k)} {_fmt(page - y * k)}"  # PDF's y runs up from the bottom

    ops = ["0 g"]
    for r in tile.rings:
        ops.append(f"{pt(*r[0])} m")
        ops.extend(f"{pt(x, y)} l" for x, y in r[1:])
        ops.append("h")
    ops.append("f*")
    if tile.marks:
        ops.append(f"0 G {_fmt(tile.mark_width * k)} w")
        for a, b in tile.marks:
            ops.append(f"{pt(*a)} m {pt(*b)} l S")
        ops.append(f"BT /F1 {_fmt(2.8 * k)} Tf {pt(tile.bleed + 4, tile.page - 2.5)} Td "
                   f"({_pdf_text(tile.label)}) Tj ET")
    content = ("\n".join(ops) + "\n").encode("latin-1")
    lo, hi = tile.bleed * k, (tile.bleed + tile.size) * k
    objects = [
        b"<< /Type /Catalog /Pages 2 0 R >>",
        b"<< /Type /Pages /Kids [3 0 R] /Count 1 >>",
        (f"<< /Type /Page /Parent 2 0 R /MediaBox [0 0 {_fmt(page)} {_fmt(page)}] "
         f"/TrimBox [{_fmt(lo)} {_fmt(lo)} {_fmt(hi)} {_fmt(hi)}] "
         f"/Resources << /Font << /F1 5 0 R >> >> /Contents 4 0 R >>").encode("ascii"),
        b"<< /Length " + str(len(content)).encode("ascii") + b" >>\nstream\n" + content + b"endstream",
        b"<< /Type /Font /Subtype /Type1 /BaseFont /Helvetica /Encoding /WinAnsiEncoding >>",
    ]
    out = bytearray(b"%PDF-1.4\n%\xe2\xe3\xcf\xd3\n")
    offsets = []
    for i, body in enumerate(objects, 1):
        offsets.append(len(out))
        out += f"{i} 0 obj\n".encode("ascii") + body + b"\nendobj\n"
    xref = len(out)
    out += f"xref\n0 {len(objects) + 1}\n".encode("ascii") + b"0000000000 65535 f \n"
    for off in offsets:
        out += f"{off:010d} 00000 n \n".encode("ascii")
    out += (f"trailer\n<< /Size {len(objects) + 1} /Root 1 0 R >>\nstartxref\n{xref}\n%%EOF\n").encode("ascii")
    return bytes(out)


def tile_image(tile: Tile, *, dpi: float = 300.0) -> np.ndarray:
    """The tile rasterized at ``dpi``: ``(H, W)`` uint8, white paper (255), black ink (0),
    antialiased; pixel ``(col, row)`` covers page millimetres ``[col, col + 1) * 25.4 / dpi``."""
    if isinstance(dpi, bool) or not isinstance(dpi, (int, float)) or not 20 <= dpi <= 2400:
        raise InputError(f"dpi: expected a number between 20 and 2400, got {dpi!r}")
    px_per_mm = dpi / 25.4
    n = int(round(tile.page * px_per_mm))
    if n > 20000:
        raise InputError(f"dpi: a {tile.page:g} mm page at {dpi:g} dpi is {n} px wide; lower the dpi")
    img = np.full((n, n), 255, np.uint8)
    # pixel centres sit at (i + 0.5) / px_per_mm millimetres
    rings_px = [r * px_per_mm - 0.5 for r in tile.rings]
    pts = np.vstack(rings_px)
    x0, y0 = np.maximum(np.floor(pts.min(axis=0)).astype(int) - 2, 0)
    x1, y1 = np.minimum(np.ceil(pts.max(axis=0)).astype(int) + 3, n)
    # supersample only the symbol's bounding box: a full 300 dpi page is millions of pixels
    alpha = coverage([r - (x0, y0) for r in rings_px], (y1 - y0, x1 - x0), supersample=4)
    img[y0:y1, x0:x1] = np.clip(np.rint(255 * (1 - alpha)), 0, 255).astype(np.uint8)
    if tile.marks:
        thick = max(1, int(round(tile.mark_width * px_per_mm)))
        sh = 4
        for a, b in tile.marks:
            pa = tuple(int(round((v * px_per_mm - 0.5) * (1 << sh))) for v in a)
            pb = tuple(int(round((v * px_per_mm - 0.5) * (1 << sh))) for v in b)
            cv2.line(img, pa, pb, 0, thick, cv2.LINE_AA, sh)
        scale = 2.8 * px_per_mm / 22.0  # Hershey simplex capitals are about 22 units tall at scale 1
        org = (int(round((tile.bleed + 4) * px_per_mm)), int(round((tile.page - 2.5) * px_per_mm)))
        cv2.putText(img, tile.label, org, cv2.FONT_HERSHEY_SIMPLEX, scale, 0, max(1, int(round(scale))),
                    cv2.LINE_AA)
    return img


def tile_png(tile: Tile, *, dpi: float = 300.0) -> bytes:
    """PNG bytes of :func:`tile_image`, with a pHYs chunk so printing software keeps the size."""
    img = tile_image(tile, dpi=dpi)
    ok, buf = cv2.imencode(".png", img)
    if not ok:  # pragma: no cover - encoding a uint8 image does not fail
        raise InputError("cannot encode the tile as PNG")
    data = buf.tobytes()
    ppm = int(round(dpi / 0.0254))
    body = b"pHYs" + struct.pack(">IIB", ppm, ppm, 1)
    chunk = struct.pack(">I", 9) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)
    ihdr_end = 8 + 8 + 13 + 4  # signature, IHDR length+type, IHDR data, CRC
    return data[:ihdr_end] + chunk + data[ihdr_end:]


def write_tile(path: str | Path, symbol: Any, *, fmt: str | None = None, dpi: float = 300.0, **layout: Any) -> Tile:
    """Lay out a tile (see :meth:`Tile.build` for ``layout``) and write it atomically as SVG, PDF or
    PNG (``fmt``, default from the file's suffix)."""
    p = Path(path)
    kind = (fmt or p.suffix.lstrip(".")).lower()
    if kind not in FORMATS:
        raise InputError(f"output: cannot tell the format of {str(p)!r}; use a .svg, .pdf or .png file "
                         f"(or format: {', '.join(FORMATS)})")
    tile = Tile.build(symbol, **layout)
    if kind == "svg":
        write_atomic(p, tile_svg(tile))
    elif kind == "pdf":
        write_atomic(p, tile_pdf(tile))
    else:
        write_atomic(p, tile_png(tile, dpi=dpi))
    return tile
