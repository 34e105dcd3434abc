"""Figures of a symbol ranking, drawn with OpenCV (no matplotlib), like the paper's figures 8-10.

- ``symbols-fd.png``: the first 20 descriptor entries (for ``fourier``: the FD amplitudes) of the
  candidates, one line each; the recommended symbol and the best and worst few of the ranking are
  coloured and named in a legend, the others drawn in light grey.
- ``symbols-mean-variance.png``: the mean distance dbar_i (top) and the variance v_i (bottom) per
  symbol, in the equation (4) ranking order; the recommended symbol in red.
- ``symbols-distances.png``: the distance matrix of equation (2) as a heat map in ranking order,
  with a colour bar.
- ``symbols-margin.png``: the confusion margin per symbol (bars) with the minimum marked.

Every figure is white with black axes, ticks with values, axis titles and a title.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import cv2
import numpy as np

from ..imageio import write_image

__all__ = ["FIGURES", "bar_panel", "distance_heatmap", "fd_figure", "margin_figure", "mean_variance_figure",
           "write_figures"]

FIGURES = ("symbols-fd.png", "symbols-mean-variance.png", "symbols-distances.png", "symbols-margin.png")

_FONT = cv2.FONT_HERSHEY_SIMPLEX
_BLACK = (0, 0, 0)
_GREY = (200, 200, 200)
# Colour-blind-safe palette (Okabe-Ito), BGR.
_PALETTE = [(178, 114, 0), (0, 159, 230), (115, 158, 0), (0, 94, 213), (167, 121, 204), (233, 180, 86),
            (66, 228, 240), (0, 0, 0)]


def _text(img, s, org, scale=0.45, color=_BLACK, thick=1, align="left", valign="base"):
    (w, h), base = cv2.getTextSize(s, _FONT, scale, thick)
    x, y = org
    if align == "center":
        x -= w // 2
    elif align == "right":
        x -= w
    if valign == "center":
        y += h // 2
    elif valign == "top":
        y += h
    cv2.putText(img, s, (int(x), int(y)), _FONT, scale, color, thick, cv2.LINE_AA)
    return w, h


def _vtext(img, s, centre, scale=0.45, color=_BLACK, thick=1, anchor="center"):
    """Text rotated 90 degrees counter-clockwise; ``anchor`` 'top' puts its end at centre's y."""
    (w, h), base = cv2.getTextSize(s, _FONT, scale, thick)
    patch = np.full((h + base + 4, w + 4, 3), 255, np.uint8)
    cv2.putText(patch, s, (2, h + 2), _FONT, scale, color, thick, cv2.LINE_AA)
    patch = cv2.rotate(patch, cv2.ROTATE_90_COUNTERCLOCKWISE)
    ph, pw = patch.shape[:2]
    x0 = int(centre[0] - pw / 2)
    y0 = int(centre[1] - ph / 2) if anchor == "center" else int(centre[1])
    x1, y1 = min(x0 + pw, img.shape[1]), min(y0 + ph, img.shape[0])
    x0c, y0c = max(x0, 0), max(y0, 0)
    if x1 > x0c and y1 > y0c:
        region = img[y0c:y1, x0c:x1]
        np.minimum(region, patch[y0c - y0:y1 - y0, x0c - x0:x1 - x0], out=region)


def _nice_ticks(lo: float, hi: float, n: int = 5) -> np.ndarray:
    if hi <= lo:
        hi = lo + 1.0
    raw = (hi - lo) / n
    mag = 10 ** np.floor(np.log10(raw))
    step = min((m * mag for m in (1, 2, 2.5, 5, 10) if m * mag >= raw), default=10 * mag)
    return np.arange(np.ceil(lo / step) * step, hi + 1e-9 * step, step)


def _fmt(v: float) -> str:
    if v == 0:
        return "0"
    return f"{v:.3g}" if abs(v) >= 0.01 else f"{v:.1e}"


def _axes(img, box, ylo, yhi, *, ylabel="", yticks=None):
    """Draw a y axis with ticks in ``box`` = (x0, y0, x1, y1); return the value -> row function."""
    x0, y0, x1, y1 = box

    def ypix(v):
        return y1 - (np.asarray(v, float) - ylo) / (yhi - ylo) * (y1 - y0)

    ticks = _nice_ticks(ylo, yhi) if yticks is None else yticks
    for t in ticks:
        y = int(round(float(ypix(t))))
        cv2.line(img, (x0, y), (x1, y), (235, 235, 235), 1)
        cv2.line(img, (x0 - 4, y), (x0, y), _BLACK, 1)
        _text(img, _fmt(float(t)), (x0 - 7, y), 0.4, align="right", valign="center")
    cv2.line(img, (x0, y0), (x0, y1), _BLACK, 1)
    cv2.line(img, (x0, y1), (x1, y1), _BLACK, 1)
    if ylabel:
        _vtext(img, ylabel, (x0 - 62, (y0 + y1) // 2), 0.45)
    return ypix


def fd_figure(names: Sequence[str], descriptors: np.ndarray, highlight: Sequence[str], *, n: int = 20,
              title: str = "First 20 descriptor entries (Fourier amplitudes |c_k|/|c_1|)",
              xlabel: str = "harmonic index k (entry of the descriptor)") -> np.ndarray:
    """Line plot of the first ``n`` descriptor entries of every candidate, shape (H, W, 3) uint8."""
    d = np.asarray(descriptors, float)[:, :n]
    k = d.shape[1]
    W, H = 1100, 620
    img = np.full((H, W, 3), 255, np.uint8)
    box = (90, 60, 820, 540)
    yhi = float(d.max()) * 1.05 if d.size else 1.0
    ypix = _axes(img, box, 0.0, yhi, ylabel="amplitude")
    xs = np.linspace(box[0] + 15, box[2] - 15, k)
    for i, x in enumerate(xs):
        cv2.line(img, (int(x), box[3]), (int(x), box[3] + 4), _BLACK, 1)
        _text(img, str(i + 1), (int(x), box[3] + 20), 0.4, align="center")
    _text(img, xlabel, ((box[0] + box[2]) // 2, box[3] + 48), 0.5, align="center")
    _text(img, title, (W // 2, 35), 0.6, align="center", thick=1)
    hl = [names.index(h) for h in highlight if h in names]
    for i in range(len(names)):
        if i in hl:
            continue
        pts = np.c_[xs, ypix(d[i])].round().astype(np.int32)
        cv2.polylines(img, [pts], False, _GREY, 1, cv2.LINE_AA)
    for j, i in enumerate(hl):
        color = _PALETTE[j % len(_PALETTE)]
        pts = np.c_[xs, ypix(d[i])].round().astype(np.int32)
        cv2.polylines(img, [pts], False, color, 2, cv2.LINE_AA)
        for p in pts:
            cv2.circle(img, tuple(int(v) for v in p), 3, color, -1, cv2.LINE_AA)
        ly = box[1] + 10 + 24 * j
        cv2.line(img, (845, ly), (875, ly), color, 2, cv2.LINE_AA)
        _text(img, names[i], (883, ly), 0.45, valign="center")
    ly = box[1] + 10 + 24 * len(hl)
    cv2.line(img, (845, ly), (875, ly), _GREY, 1, cv2.LINE_AA)
    _text(img, "other candidates", (883, ly), 0.45, valign="center")
    return img


def bar_panel(img, box, labels, values, *, ylabel, color, title="", under=None, mark=None, line=None,
              show_labels=True):
    """Vertical bars in ``box`` (x0, y0, x1, y1); labels rotated under the axis."""
    x0, y0, x1, y1 = box
    vals = np.asarray(values, float)
    finite = vals[np.isfinite(vals)]
    yhi = float(finite.max()) * 1.08 if finite.size and finite.max() > 0 else 1.0
    if line is not None:
        yhi = max(yhi, line * 1.15)
    ypix = _axes(img, box, 0.0, yhi, ylabel=ylabel)
    n = len(vals)
    slot = (x1 - x0) / max(n, 1)
    for i, v in enumerate(vals):
        cx = x0 + slot * (i + 0.5)
        top = float(ypix(min(v, yhi))) if np.isfinite(v) else float(y0)
        c = (0, 0, 200) if mark is not None and mark[i] else color
        cv2.rectangle(img, (int(cx - slot * 0.35), int(round(top))), (int(cx + slot * 0.35), y1 - 1), c, -1)
        if show_labels:
            _vtext(img, labels[i], (int(cx), y1 + 6), 0.4, anchor="top")
        if under is not None:
            _text(img, under[i], (int(cx), y1 + 14), 0.3, align="center")
    if line is not None:
        y = int(round(float(ypix(line))))
        cv2.line(img, (x0, y), (x1, y), (0, 0, 200), 1, cv2.LINE_AA)
        _text(img, f"minimum {line:g}", (x1 - 4, y - 5), 0.4, color=(0, 0, 200), align="right")
    if title:
        _text(img, title, ((x0 + x1) // 2, y0 - 12), 0.5, align="center")


def mean_variance_figure(names, mean, variance, order, recommended=None) -> np.ndarray:
    """Mean distance and variance per symbol in ranking order (paper figures 9 and 10)."""
    n = len(names)
    W = max(900, 120 + 26 * n)
    H = 830
    img = np.full((H, W, 3), 255, np.uint8)
    labels = [names[i] for i in order]
    mark = [names[i] == recommended for i in order]
    _text(img, "Equation (3) per symbol, in equation (4) ranking order (best left)", (W // 2, 28), 0.6,
          align="center")
    bar_panel(img, (100, 75, W - 30, 330), labels, np.asarray(mean)[order], ylabel="mean distance",
              color=(178, 114, 0), title="mean distance  dbar_i = (1/M) sum_j d_ij", mark=mark, show_labels=False)
    bar_panel(img, (100, 400, W - 30, 655), labels, np.asarray(variance)[order], ylabel="variance",
              color=(0, 159, 230), title="variance  v_i = 1/(M-1) sum_j (d_ij - dbar_i)^2", mark=mark)
    if recommended:
        _text(img, f"red: recommended symbol ({recommended})", (100, H - 15), 0.45, color=(0, 0, 200))
    return img


def margin_figure(names, margin, order, min_margin, recommended=None) -> np.ndarray:
    """Confusion margin per symbol in ranking order, with the minimum a recommendation needs."""
    n = len(names)
    W = max(900, 120 + 26 * n)
    img = np.full((470, W, 3), 255, np.uint8)
    labels = [names[i] for i in order]
    mark = [names[i] == recommended for i in order]
    _text(img, "Confusion margin: nearest noise contour / own spread under rendering changes", (W // 2, 28), 0.6,
          align="center")
    bar_panel(img, (100, 70, W - 30, 320), labels, np.asarray(margin)[order], ylabel="margin",
              color=(115, 158, 0), mark=mark, line=min_margin)
    return img


def _colormap(values01: np.ndarray) -> np.ndarray:
    """Viridis colours (BGR uint8) for values in [0, 1]."""
    v = np.clip(np.asarray(values01, float), 0, 1)
    lut = cv2.applyColorMap(np.arange(256, dtype=np.uint8)[:, None], cv2.COLORMAP_VIRIDIS)[:, 0, :]
    return lut[np.rint(v * 255).astype(int)]


def distance_heatmap(names, distances, order, recommended=None) -> np.ndarray:
    """The equation (2) distance matrix as a heat map, rows and columns in ranking order."""
    n = len(names)
    cell = max(10, min(22, 700 // max(n, 1)))
    left, top = 150, 70
    W = left + n * cell + 140
    H = top + n * cell + 140
    img = np.full((H, W, 3), 255, np.uint8)
    d = np.asarray(distances, float)[np.ix_(order, order)]
    dmax = float(d.max()) if d.size and d.max() > 0 else 1.0
    colors = _colormap(d / dmax)
    block = np.repeat(np.repeat(colors, cell, axis=0), cell, axis=1)
    img[top:top + n * cell, left:left + n * cell] = block
    cv2.rectangle(img, (left - 1, top - 1), (left + n * cell, top + n * cell), _BLACK, 1)
    for i, idx in enumerate(order):
        c = (0, 0, 200) if names[idx] == recommended else _BLACK
        _text(img, names[idx], (left - 6, top + i * cell + cell // 2), 0.38, color=c, align="right", valign="center")
        _vtext(img, names[idx], (left + i * cell + cell // 2, top + n * cell + 6), 0.38, color=c, anchor="top")
    _text(img, "Equation (2) distance matrix d_ij (ranking order, best top-left)", (W // 2, 35), 0.55,
          align="center")
    # colour bar
    bx0, by0, bh = left + n * cell + 30, top, n * cell
    ramp = _colormap(np.linspace(1, 0, bh))[:, None, :]
    img[by0:by0 + bh, bx0:bx0 + 18] = np.repeat(ramp, 18, axis=1)
    cv2.rectangle(img, (bx0 - 1, by0 - 1), (bx0 + 18, by0 + bh), _BLACK, 1)
    for t in _nice_ticks(0, dmax, 5):
        y = int(round(by0 + bh - t / dmax * bh))
        cv2.line(img, (bx0 + 18, y), (bx0 + 23, y), _BLACK, 1)
        _text(img, _fmt(float(t)), (bx0 + 27, y), 0.38, valign="center")
    _vtext(img, "distance", (bx0 + 95, by0 + bh // 2), 0.45)
    return img


def write_figures(ranking, folder: str | Path, *, highlight: int = 3) -> list[Path]:
    """Write the four figures of a :class:`sbplan.symbols.rank.Ranking` into ``folder``."""
    out = Path(folder)
    names = list(ranking.names)
    order = list(ranking.order)
    chosen = [ranking.recommended] if ranking.recommended else []
    chosen += [names[i] for i in order[:highlight]] + [names[i] for i in order[-highlight:]]
    for extra in ("circle", "flag"):
        if extra in names:
            chosen.append(extra)
    chosen = list(dict.fromkeys(chosen))
    matcher = ranking.settings.get("stages", {}).get("matcher", {}).get("name", "")
    title = ("First 20 Fourier-descriptor amplitudes |c_k|/|c_1| per candidate" if matcher == "fourier"
             else f"First 20 descriptor entries per candidate ({matcher})")
    xlabel = ("entry: k = -1..-10, then k = 2..11" if matcher == "fourier" else "descriptor entry")
    figures = {
        FIGURES[0]: fd_figure(names, ranking.descriptors, chosen, title=title, xlabel=xlabel),
        FIGURES[1]: mean_variance_figure(names, ranking.mean, ranking.variance, order, ranking.recommended),
        FIGURES[2]: distance_heatmap(names, ranking.distances, order, ranking.recommended),
        FIGURES[3]: margin_figure(names, ranking.margin, order, ranking.settings["min_margin"], ranking.recommended),
    }
    return [write_image(out / name, img) for name, img in figures.items()]
