"""Printable tiles (SVG, PDF, PNG), the terminal drawing and the ``sbplan symbols`` command."""

from __future__ import annotations

import json
import re
import shutil
import struct
import subprocess
import xml.etree.ElementTree as ET

import cv2
import numpy as np
import pytest
from shapely.geometry import Polygon

from sbplan.cli import main
from sbplan.errors import InputError
from sbplan.symbols.raster import symbol_rings
from sbplan.symbols.terminal import draw
from sbplan.symbols.tile import Tile, parse_length, tile_image, tile_pdf, tile_png, tile_svg, write_tile
from sbplan.synth import rings_centroid

PT = 72 / 25.4


def expected_area(name: str, symbol_mm: float) -> float:
    return rings_centroid(symbol_rings(name))[1] * symbol_mm ** 2


def even_odd_polygon(rings) -> Polygon:
    return Polygon(rings[0], rings[1:])


@pytest.mark.parametrize("text, mm", [("200mm", 200), ("20cm", 200), ("0.2m", 200), ("8in", 203.2),
                                      (" 72pt", 25.4), ("150", 150), (90.5, 90.5)])
def test_parse_length(text, mm):
    assert parse_length(text) == pytest.approx(mm)


@pytest.mark.parametrize("text", ["", "2x", "-5mm", "0mm", "mm", "1e999mm"])
def test_parse_length_rejects_bad_lengths(text):
    with pytest.raises(InputError, match="size"):
        parse_length(text)


def test_tile_layout_centres_the_symbols_centre_of_area():
    t = Tile.build("flag", size="200mm", angle=25)
    assert t.page == pytest.approx(224) and t.symbol_size == pytest.approx(90)
    c, area = rings_centroid(t.rings)
    np.testing.assert_allclose(c, [112, 112], atol=1e-9)
    assert area == pytest.approx(expected_area("flag", 90))
    assert len(t.marks) == 12 and "flag" in t.label
    bare = Tile.build("flag", size=200, crop_marks=False)
    assert bare.page == 200 and bare.marks == [] and bare.label == ""


@pytest.mark.parametrize("kwargs, word", [
    (dict(symbol_fraction=1.2), "symbol_fraction"), (dict(symbol_fraction=0.99, angle=45), "symbol_size"),
    (dict(bleed="3mm"), "bleed"), (dict(size="big"), "size"), (dict(angle=float("nan")), "angle"),
])
def test_tile_rejects_bad_layouts(kwargs, word):
    with pytest.raises(InputError, match=word):
        Tile.build("flag", **kwargs)


def test_svg_is_in_millimetres_and_holds_the_symbol():
    t = Tile.build("letter-a", size="150mm", angle=10)
    root = ET.fromstring(tile_svg(t))
    assert root.get("width") == "174mm" and root.get("viewBox") == "0 0 174 174"
    ns = {"s": "http://www.w3.org/2000/svg"}
    sym = root.find("s:path[@id='symbol']", ns)
    assert sym.get("fill-rule") == "evenodd"
    rings = [np.array(re.findall(r"(-?[\d.]+) (-?[\d.]+)", part), float)
             for part in sym.get("d").split("Z") if part.strip()]
    assert len(rings) == 2  # the A's outline and its hole
    poly = even_odd_polygon(rings)
    assert poly.area == pytest.approx(expected_area("letter-a", 0.45 * 150), rel=1e-4)
    assert poly.centroid.x == pytest.approx(87, abs=1e-3) and poly.centroid.y == pytest.approx(87, abs=1e-3)
    assert root.find("s:path[@id='crop-marks']", ns) is not None


def _pdf_paths(data: bytes):
    stream = re.search(rb"stream\n(.*?)endstream", data, re.S).group(1).decode("latin-1")
    rings, cur = [], []
    for line in stream.splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[2] in ("m", "l"):
            if parts[2] == "m" and cur:
                rings.append(cur)
                cur = []
            cur.append((float(parts[0]), float(parts[1])))
        elif parts == ["h"]:
            rings.append(cur)
            cur = []
        elif parts == ["f*"]:
            break
    return rings


def test_pdf_is_a_valid_vector_page_in_points():
    t = Tile.build("letter-p", size="200mm")
    data = tile_pdf(t)
    assert data.startswith(b"%PDF-1.4") and data.rstrip().endswith(b"%%EOF")
    page = 224 * PT
    assert f"/MediaBox [0 0 {page:.4f}".rstrip("0").encode() in data
    # the cross-reference table points at each object
    xref = int(re.search(rb"startxref\n(\d+)", data).group(1))
    assert data[xref:xref + 4] == b"xref"
    offsets = [int(o) for o in re.findall(rb"(\d{10}) 00000 n", data)]
    for i, off in enumerate(offsets, 1):
        assert data[off:].startswith(f"{i} 0 obj".encode())
    length = int(re.search(rb"/Length (\d+)", data).group(1))
    assert re.search(rb"stream\n(.*?)endstream", data, re.S).group(1).__len__() == length
    # the filled path, back in millimetres with y down, is the symbol at the page centre
    rings = [np.array([(x / PT, (page - y) / PT) for x, y in r]) for r in _pdf_paths(data)]
    poly = even_odd_polygon(rings)
    assert poly.area == pytest.approx(expected_area("letter-p", 90), rel=1e-4)
    c, _ = rings_centroid(rings)
    np.testing.assert_allclose(c, [112, 112], atol=1e-3)


@pytest.mark.skipif(shutil.which("pdftoppm") is None, reason="poppler's pdftoppm is not installed")
def test_pdf_renders_like_the_png(tmp_path):
    t = Tile.build("flag", size="100mm", crop_marks=False)
    (tmp_path / "t.pdf").write_bytes(tile_pdf(t))
    subprocess.run(["pdftoppm", "-r", "100", "-gray", "-png", str(tmp_path / "t.pdf"), str(tmp_path / "r")],
                   check=True, capture_output=True)
    rendered = cv2.imread(str(next(tmp_path.glob("r*.png"))), cv2.IMREAD_GRAYSCALE)
    ours = tile_image(t, dpi=100)
    assert abs(rendered.shape[0] - ours.shape[0]) <= 1
    n = min(rendered.shape[0], ours.shape[0])
    ink_pdf, ink_png = (rendered[:n, :n] < 128), (ours[:n, :n] < 128)
    assert ink_pdf.sum() == pytest.approx(ink_png.sum(), rel=0.02)
    assert (ink_pdf ^ ink_png).sum() < 0.03 * ink_png.sum()


def test_png_has_the_stated_dpi_and_the_symbol_at_its_size():
    dpi = 150
    t = Tile.build("cross-latin", size="200mm")
    data = tile_png(t, dpi=dpi)
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and data[37:41] == b"pHYs"
    ppm_x, ppm_y, unit = struct.unpack(">IIB", data[41:50])
    assert unit == 1 and ppm_x == ppm_y == round(dpi / 0.0254)
    img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_GRAYSCALE)
    px = dpi / 25.4
    assert img.shape == (round(224 * px), round(224 * px))
    lo, hi = int(round(12 * px)), int(round(212 * px))
    ink = (255 - img[lo:hi, lo:hi].astype(float)) / 255  # inside the trim box: the symbol only
    assert ink.sum() / px ** 2 == pytest.approx(expected_area("cross-latin", 90), rel=0.01)
    ys, xs = np.mgrid[lo:hi, lo:hi]
    cx, cy = (ink * xs).sum() / ink.sum(), (ink * ys).sum() / ink.sum()
    assert (cx + 0.5) / px == pytest.approx(112, abs=0.2) and (cy + 0.5) / px == pytest.approx(112, abs=0.2)
    assert (img[:lo, :] < 128).any()  # crop marks in the margin


def test_write_tile_picks_the_format_from_the_suffix(tmp_path):
    for ext, magic in (("svg", b"<?xml"), ("pdf", b"%PDF"), ("png", b"\x89PNG")):
        write_tile(tmp_path / f"t.{ext}", "stairs", size="10cm", dpi=50)
        assert (tmp_path / f"t.{ext}").read_bytes().startswith(magic)
    with pytest.raises(InputError, match="output"):
        write_tile(tmp_path / "t.jpg", "stairs")
    assert not (tmp_path / "t.jpg").exists()


def test_terminal_half_blocks_and_braille():
    lines = draw("square", width=12).splitlines()
    assert all(len(line) == 12 for line in lines)
    assert set("".join(lines)) <= set(" ▀▄█")
    assert lines[len(lines) // 2].strip() == "█" * 10
    art = draw("ring", width=20, mode="braille").splitlines()
    assert all(len(line) == 20 and all(0x2800 <= ord(ch) <= 0x28FF for ch in line) for line in art)
    mid = art[len(art) // 2]
    assert mid[10] == chr(0x2800) and mid[2] != chr(0x2800)  # the hole in the middle, ink at the rim
    flipped = draw("square", width=12, invert=True).splitlines()
    assert flipped[len(flipped) // 2] == "█" + " " * 10 + "█"  # the margin is inked, the square blank
    with pytest.raises(InputError, match="mode"):
        draw("flag", mode="ascii")
    with pytest.raises(InputError, match="width"):
        draw("flag", width=2)


def test_cli_render_show_and_errors(tmp_path, capsys):
    out = tmp_path / "tile.svg"
    assert main(["symbols", "render", "flag", "--size", "25cm", "-o", str(out)]) == 0
    assert ET.fromstring(out.read_text()).get("width") == "274mm"
    assert main(["symbols", "show", "flag", "--width", "16"]) == 0
    shown = capsys.readouterr().out.splitlines()
    assert any("█" in line for line in shown)
    assert main(["symbols", "render", "nope", "-o", str(tmp_path / "x.pdf")]) == 2
    assert "sbplan: error:" in capsys.readouterr().err
    assert main(["symbols", "render", "flag", "--size", "2x", "-o", str(tmp_path / "x.pdf")]) == 2


def test_cli_rank_json_and_plots(tmp_path, capsys):
    args = ["symbols", "rank", "flag", "circle", "letter-k", "cross", "--noise-count", "3",
            "--plot", str(tmp_path / "fig"), "--json"]
    assert main(args) == 0
    data = json.loads(capsys.readouterr().out)
    assert [c["rank"] for c in data["candidates"]] == [1, 2, 3, 4]
    assert {c["name"] for c in data["candidates"]} == {"flag", "circle", "letter-k", "cross"}
    assert data["recommended"] != "circle"
    for name in ("symbols-fd.png", "symbols-mean-variance.png", "symbols-distances.png", "symbols-margin.png"):
        img = cv2.imread(str(tmp_path / "fig" / name))
        assert img is not None and img.shape[0] > 200 and (img < 128).any()
    assert main(["symbols", "rank", "flag", "--noise-set", "glare"]) == 2
