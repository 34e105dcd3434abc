"""Obstacle footprints: how far each obstacle reaches, in and around its occupied cells.

The paper's occupancy decides *where* obstacles are: a cell whose symbol is hidden is occupied.
Whole cells make poor outlines, though: an obstacle reaches past its cells into the gaps between
symbols (too small where it matters), and covers a fraction of a cell whose symbol it clips (too
large where it hurts). Two footprints are built here, each a stage of kind ``footprint``
(``plugins/sbplan_footprints/``):

- :func:`cell_outlines` (stage ``cells``): the occupancy image's black regions, as the paper has it.
- :func:`pixel_outlines` (stage ``pixels``, the default): each obstacle's outline found in the
  pixels, in and around its occupied cells, against the reference image.

How the pixels decide, on the reference and the frame made four times smaller (the reference
thumbnail the calibration keeps for registration, and the frame averaged the same way and moved
into the calibration's pixels when the camera moved), within the occupied cells and their
neighbours:

1. **Seeds.** Where an obstacle certainly stands and where the floor certainly shows. Each occupied
   cell's symbol outline is probed as the detector's edge check probes it (1.5 px inside and
   outside 128 points, :func:`~sbplan.detection.outline_checks.edge_kept`): a run of points whose
   ink-to-floor step is gone is hidden (obstacle: on the ink, and :data:`OBSTACLE_SEED_PX` beyond
   it, where the obstacle that hides the edge stands); a run that keeps it is visible (floor, on
   both sides). Free cells' symbols and the floor just around them are floor, and so is everything
   beyond the occupied cells' neighbours. Areas printed with texture the reference does not have
   (an obstacle's print, stripes, labels) that reach into an occupied cell are obstacle; an opening
   keeps areas only, so wear's thin lines (tyre marks, scratches) are not taken.
2. **Regions.** A marker-based watershed (``cv2.watershed``) grows the seeds over the frame's grey
   levels, on a logarithmic scale (light multiplies: a step is a ratio) with the symbols' ink
   painted over by the floor around it (so that the ink of a visible symbol and of a hidden one
   are no walls), smoothed by 3 x 3 (an obstacle's fine print is no wall either). Floor and
   obstacle meet where the frame steps most between them: at the obstacle's edge. A soft cast
   shadow or a lighting gradient changes the floor over tens of pixels, a slope rather than a
   step: the floor's region runs through it.
3. **Support.** Beyond its occupied cells an obstacle is found by the pixels alone; where they say
   nothing (a white box on a floor the light saturates), the regions meet anywhere. A piece of the
   region outside the occupied cells stays only when :data:`SUPPORT` of its pixels changed: a
   level :data:`CHANGE_LEVEL` (log) off the light around (measured on the floor seeds), or print.
4. **Shape.** Where an obstacle's edge does not stand out from the floor (a grey box on a grey
   floor), the floor's region can leak in along that stretch of its edge and leave a bay.
   Obstacles seen from above are mostly convex: each piece (after an opening that parts pieces
   touching at a corner or by a thin neck) has the bays of its convex hull filled, unless a bay is
   larger than :data:`BAY_SHARE` of the piece and holds floor seeds (the notch between two
   obstacles touching at a corner, with a visible symbol in it, is floor). Non-convex obstacles
   pay for it in area, never in recall.
5. **Margin.** The region is grown by one pixel of the smaller image (4 px), clipped to the grid's
   area, traced and simplified (by 0.7 of a small pixel, inside the margin).

Every occupied cell keeps an obstacle: a cell no refined outline reaches gets its cell outline.
Calibration files without the reference thumbnail or the edge contrast (written before they
existed) get the cell outlines.

Why the thumbnail and not the full reference: the refinement works on 4 x 4 blocks (the watershed
on the full frame would cost 16 times as much), and the thumbnail is exactly those blocks' means of
the reference. Storing the full reference (about 1 MB of base64 PNG per calibration file) would
buy a boundary resolution of 1 px that the margin spends anyway.

Coordinates: outlines are ``(x, y)`` calibration pixels; the frame's pixel ``(col, row)`` covers
``[col - 0.5, col + 0.5]``; the smaller images' pixel ``(j, i)`` covers the frame's pixels
``4 j .. 4 j + 3`` and ``4 i .. 4 i + 3`` (centre ``(4 j + 1.5, 4 i + 1.5)``).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..errors import InputError
from ..imageio import halve
from .outline_checks import EDGE_DEPTH_PX, EDGE_SAMPLES, edge_factors, edge_kept, edge_probes
from .registration import THUMBNAIL_FACTOR, CameraMotion, apply

#: A run of this many points on each side of an outline point must agree with it (all hidden, or
#: all visible) for the point to seed a region: single points flip with noise and wear.
SEED_RUN = 2
#: A bay of a piece's convex hull is filled when it is at most this share of the piece (and holds
#: no floor seed): a stretch of an obstacle's edge the floor leaked through leaves a bay.
BAY_SHARE = 0.15
#: A piece of a footprint outside its occupied cells stays when this share of its pixels shows a
#: change from the reference (:func:`_supported`): a level CHANGE_LEVEL (log) off the light around.
SUPPORT = 0.25
CHANGE_LEVEL = 0.1
#: Side (small pixels) of the opening that keeps printed areas and drops thin textured lines.
PRINT_OPEN = 9
#: How far (pixels) beyond a hidden stretch of a symbol's outline the obstacle is seeded as well.
OBSTACLE_SEED_PX = 8.0
#: Log grey-level units per level of the watershed's 8-bit image (a step of 1 % is one level).
LOG_LEVELS = 100.0
#: The texture (mean absolute difference from the 3 x 3 mean, log units, over 5 x 5) above which
#: a pixel of an occupied cell is taken for an obstacle's print: the floor stays under 0.02 in the
#: renderer's noisiest condition, printed obstacles reach 0.05 and more.
TEXTURE_SEED = 0.05


@dataclass(frozen=True, eq=False)
class FootprintReference:
    """What :func:`pixel_outlines` needs of a calibration, computed once (:func:`footprint_reference`).

    Arrays at the small scale (``scale`` times smaller than the frame) are ``(h, w)``; probes are
    in calibration pixels.

    Attributes
    ----------
    scale : int
    reference : ndarray (h, w), float32
        The reference, averaged over ``scale x scale`` blocks.
    ink : ndarray (h, w), bool
        The symbols' ink grown by one pixel (painted over in the frame).
    near_ink : ndarray (h, w), bool
        The ink grown by three pixels: where painted and unpainted pixels meet, texture says nothing.
    floor_weight, floor_weight_sum : ndarray (h, w), float32
        1 off the ink, and its box mean over ``paint`` pixels (where the painting reads from).
    paint : int
        Side of the box the ink is painted from: the symbols' size and a little more, so that the
        box around any ink pixel reaches the floor.
    ink_cores : list of ndarray
        Per cell (flat, row-major), the flat indices of its symbol's ink core's pixels.
    log_reference : ndarray (h, w), float32
        ``log(max(reference, 1))``.
    probe_x, probe_y : ndarray (cells, 2, S), float32
        :func:`~sbplan.detection.outline_checks.edge_probes` of every cell's reference outline.
    factors : ndarray (cells, S), float32
        :func:`~sbplan.detection.outline_checks.edge_factors` of the calibration's edge contrast.
    cell_quads : ndarray (rows, cols, 4, 2), float64
        Each cell's corners at the small scale.
    grid_area : ndarray (h, w), bool
        The cells' union: footprints stop at the floor's edge.
    quads_fixed : ndarray (rows, cols, 4, 2), int32
        ``cell_quads`` in OpenCV's fixed point (4 fractional bits), ready to fill.
    floor_seed_ij : ndarray (2, K), int64
        Small pixels ``(i, j)`` of every symbol's ink core and of its outline's outer probes: floor
        when its cell is free.
    floor_seed_cell : ndarray (K,), int64
        The (flat) cell of each of them.
    probe_ij : ndarray (2, cells, 3, S), int64
        Small pixels ``(i, j)`` of each outline point's inner probe, outer probe and obstacle seed
        beyond it (:data:`OBSTACLE_SEED_PX`).
    """

    scale: int
    reference: np.ndarray
    ink: np.ndarray
    near_ink: np.ndarray
    floor_weight: np.ndarray
    floor_weight_sum: np.ndarray
    paint: int
    ink_cores: list
    log_reference: np.ndarray
    probe_x: np.ndarray
    probe_y: np.ndarray
    factors: np.ndarray
    cell_quads: np.ndarray
    grid_area: np.ndarray
    quads_fixed: np.ndarray
    floor_seed_ij: np.ndarray
    floor_seed_cell: np.ndarray
    probe_ij: np.ndarray


def _small(xy: np.ndarray, scale: int) -> np.ndarray:
    """Calibration pixels -> coordinates of the ``scale`` times smaller image (pixel centres on
    integers)."""
    return (np.asarray(xy, dtype=np.float64) + 0.5) / scale - 0.5


def _full(xy: np.ndarray, scale: int) -> np.ndarray:
    """The inverse of :func:`_small`."""
    return (np.asarray(xy, dtype=np.float64) + 0.5) * scale - 0.5


def _fill(shape: tuple[int, int], polygons: list[np.ndarray]) -> np.ndarray:
    """The pixels whose centres lie inside ``polygons`` ((K, 2) ``(x, y)`` each), as uint8 0/1."""
    out = np.zeros(shape, np.uint8)
    if len(polygons):
        cv2.fillPoly(out, [np.rint(np.asarray(p) * 16).astype(np.int32) for p in polygons], 1, cv2.LINE_8,
                     shift=4)
    return out


def footprint_reference(calibration) -> FootprintReference | None:
    """The per-calibration part of :func:`pixel_outlines`, or None when the calibration lacks the
    reference thumbnail or the symbols' edge contrast (files written before either existed)."""
    cal = calibration
    thumb = cal.reference_thumbnail
    n = len(cal.symbol_polygons)
    if (thumb is None or cal.edge_contrast is None or not n
            or np.shape(cal.edge_contrast) != (n, EDGE_SAMPLES)):
        return None
    scale = THUMBNAIL_FACTOR
    h, w = cal.image_shape
    if thumb.shape != (h // scale, w // scale):
        return None
    shape = thumb.shape
    small_polys = [_small(p, scale) for p in cal.symbol_polygons]
    ink = np.zeros(shape, np.uint8)
    cores = []
    one = np.ones((3, 3), np.uint8)
    for p in small_polys:
        m = _fill(shape, [p])
        ink |= m
        cores.append(np.flatnonzero(cv2.erode(m, one)))
    grown = cv2.dilate(ink, one) > 0
    weight = (~grown).astype(np.float32)
    extent = max(float(np.ptp(p, axis=0).max()) for p in small_polys)
    paint = 2 * int(np.ceil(extent / 2)) + 5
    weight_sum = np.maximum(cv2.blur(weight, (paint, paint)), np.float32(1e-3))
    x, y = edge_probes(cal.symbol_polygons)
    corners = _small(cal.grid.cell_corners_px(), scale)
    quads = np.stack([corners[:-1, :-1], corners[:-1, 1:], corners[1:, 1:], corners[1:, :-1]], axis=2)
    ring = np.concatenate([corners[0, :], corners[1:, -1], corners[-1, -2::-1], corners[-2:0:-1, 0]])
    near_ink = cv2.dilate(ink, np.ones((7, 7), np.uint8)) > 0
    reference = thumb.astype(np.float32)
    # what each frame marks, in small pixels, found once: the free symbols' floor seeds ...
    outer_i, outer_j = _small_pixel(x[:, 1], y[:, 1], scale)
    seed_i = np.concatenate([np.concatenate([c // shape[1] for c in cores]), outer_i.ravel()])
    seed_j = np.concatenate([np.concatenate([c % shape[1] for c in cores]), outer_j.ravel()])
    seed_cell = np.concatenate([np.repeat(np.arange(n), [len(c) for c in cores]),
                                np.repeat(np.arange(n), x.shape[-1])])
    # ... and the outline points' probes and the obstacle seeds beyond them
    out = OBSTACLE_SEED_PX / (2 * EDGE_DEPTH_PX)
    ox = x[:, 1] + out * (x[:, 1] - x[:, 0])
    oy = y[:, 1] + out * (y[:, 1] - y[:, 0])
    probe = np.stack([np.stack(_small_pixel(px, py, scale), axis=1)
                      for px, py in ((x[:, 0], y[:, 0]), (x[:, 1], y[:, 1]), (ox, oy))], axis=2)
    return FootprintReference(scale, reference, grown, near_ink, weight, weight_sum, paint, cores,
                              cv2.log(np.maximum(reference, np.float32(1))), x, y,
                              edge_factors(cal.edge_contrast), quads, _fill(shape, [ring]) > 0,
                              np.rint(quads * 16).astype(np.int32), np.stack([seed_i, seed_j]), seed_cell,
                              np.moveaxis(probe, 1, 0))


def _small_pixel(x: np.ndarray, y: np.ndarray, scale: int) -> tuple[np.ndarray, np.ndarray]:
    """The small image's pixels ``(i, j)`` holding the calibration points ``x``, ``y``."""
    return np.floor(y / scale).astype(np.int64), np.floor(x / scale).astype(np.int64)


def _downsample(gray: np.ndarray, scale: int, shape: tuple[int, int]) -> np.ndarray:
    """The frame averaged over ``scale x scale`` blocks, as the calibration's thumbnail was made
    (:func:`sbplan.detection.registration.thumbnail`), float32 of ``shape``."""
    h, w = gray.shape
    if scale == 4 and h % 4 == 0 and w % 4 == 0:
        # two halvings: OpenCV's fast path for a factor of 2, the same block means
        small = halve(halve(gray))
    else:
        small = cv2.resize(gray, (shape[1], shape[0]), interpolation=cv2.INTER_AREA)
    return small.astype(np.float32)


def _in_calibration(gray: np.ndarray, camera: CameraMotion, scale: int, box: tuple[int, int, int, int]) -> np.ndarray:
    """The window ``box`` (x0, y0, x1, y1, small calibration pixels) of the calibration's view,
    read from the moved frame ``gray`` (H, W), averaged over ``scale x scale`` blocks as the
    reference thumbnail was, float32.

    The frame's ``scale x scale`` box means are taken at every pixel and sampled (bilinearly)
    where each block's corner moved to. For a translation this is exactly the block means of the
    frame warped at its full resolution (box and bilinear interpolation commute), at a third of
    the cost (the full-resolution warp was a third of the whole footprint); for the camera's small
    rotations and zooms the blocks turn by well under a tenth of a pixel. Warping the frame's block
    means instead blurs every edge by the interpolation between blocks: under a 0.7 px shift the
    obstacles' recall fell from 0.997 to 0.991 (0.976 under the suite's drift).
    """
    x0, y0, x1, y1 = box
    h, w = gray.shape
    # small window pixel (j, i) -> its block's centre in calibration pixels -> frame pixels
    to_cal = np.array([[scale, 0, x0 * scale + (scale - 1) / 2], [0, scale, y0 * scale + (scale - 1) / 2], [0, 0, 1.0]])
    m = camera.matrix @ to_cal
    corners = np.array([[0, 0], [x1 - x0 - 1, 0], [0, y1 - y0 - 1], [x1 - x0 - 1, y1 - y0 - 1]], np.float64)
    q = apply(m, corners)
    # the frame's part the blocks read (a box mean reaches scale - 1 pixels right and down)
    half = (scale - 1) / 2
    fx0 = int(np.clip(np.floor(q[:, 0].min() - half) - 1, 0, w - 1))
    fy0 = int(np.clip(np.floor(q[:, 1].min() - half) - 1, 0, h - 1))
    fx1 = int(np.clip(np.ceil(q[:, 0].max() + half) + 2, fx0 + 1, w))
    fy1 = int(np.clip(np.ceil(q[:, 1].max() + half) + 2, fy0 + 1, h))
    sums = cv2.boxFilter(gray[fy0:fy1, fx0:fx1], cv2.CV_32F, (scale, scale), anchor=(0, 0),
                         borderType=cv2.BORDER_REPLICATE)
    # block centre -> the top-left corner of the box around it, in the crop's pixels
    corner = np.array([[1.0, 0, -half - fx0], [0, 1.0, -half - fy0], [0, 0, 1.0]]) @ m
    size = (x1 - x0, y1 - y0)
    if np.allclose(corner[2], (0, 0, 1)):
        return cv2.warpAffine(sums, corner[:2], size, flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                              borderMode=cv2.BORDER_REPLICATE)
    return cv2.warpPerspective(sums, corner, size, flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                               borderMode=cv2.BORDER_REPLICATE)


def _runs(flags: np.ndarray, run: int) -> np.ndarray:
    """Points whose ``run`` neighbours on each side along the closed outline share their flag:
    (n, S) bool, True where ``flags`` and its neighbours are all True."""
    out = flags.copy()
    for k in range(1, run + 1):
        out &= np.roll(flags, k, axis=1) & np.roll(flags, -k, axis=1)
    return out


def cell_outlines(occupancy: np.ndarray, occupied: np.ndarray | None = None, grid=None) -> list[np.ndarray]:
    """The occupancy image's black regions' outer outlines (paper section 4.1).

    Parameters
    ----------
    occupancy : ndarray of shape (H, W), uint8
        0 where occupied.
    occupied : ndarray of shape (rows, cols), bool, optional
    grid : sbplan.detection.grid.Grid, optional
        With both, each group of touching occupied cells is traced in its own box (the group's
        cells a cell wider all round), not the whole image: on a 4K frame, tracing the whole image
        cost ten times the rest of the step. A mapper may draw past its cells (blocks): where black
        reaches the border of a box, the whole image is traced.

    Returns
    -------
    list of ndarray (K, 2), float64
        ``(x, y)`` pixel centres of each region's outer boundary, in OpenCV's order.
    """
    occupancy = np.asarray(occupancy)
    if occupancy.ndim != 2:
        raise InputError(f"occupancy: expected a 2-D image, got shape {occupancy.shape}")
    contours = _black_regions(occupancy, occupied, grid)
    return [c[:, 0, :].astype(np.float64) for c in contours]


def _black_regions(occupancy: np.ndarray, occupied: np.ndarray | None, grid) -> list[np.ndarray]:
    """The outer contours of the occupancy image's black regions (OpenCV's, in image pixels)."""
    h, w = occupancy.shape
    if occupied is not None and grid is not None:
        if not occupied.any():
            return []
        n, labels = cv2.connectedComponents(occupied.astype(np.uint8), connectivity=8)
        corners = grid.cell_corners_px()
        contours: list[np.ndarray] = []
        for label in range(1, n):
            rows, cols = np.nonzero(labels == label)
            r0, r1 = max(int(rows.min()) - 1, 0), min(int(rows.max()) + 2, grid.rows)
            c0, c1 = max(int(cols.min()) - 1, 0), min(int(cols.max()) + 2, grid.cols)
            pts = corners[r0:r1 + 1, c0:c1 + 1].reshape(-1, 2)
            x0, y0 = (max(int(v), 0) for v in np.floor(pts.min(axis=0)) - 2)
            x1, y1 = int(min(np.ceil(pts[:, 0].max()) + 3, w)), int(min(np.ceil(pts[:, 1].max()) + 3, h))
            mask = (occupancy[y0:y1, x0:x1] == 0).astype(np.uint8)
            edge = (x0 > 0 and mask[:, 0].any()) or (y0 > 0 and mask[0].any()) or \
                   (x1 < w and mask[:, -1].any()) or (y1 < h and mask[-1].any())
            if edge:
                break
            found, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE, offset=(x0, y0))
            contours.extend(found)
        else:
            return contours
    mask = (occupancy == 0).astype(np.uint8)
    if not mask.any():
        return []
    return list(cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)[0])


def pixel_outlines(gray: np.ndarray, occupied: np.ndarray, reference: FootprintReference, *,
                   camera: CameraMotion | None = None, reach: float = 1.0, margin: int = 1,
                   texture_seed: float = TEXTURE_SEED, neck: int = 3, support: float = SUPPORT, debug: dict | None = None) -> list[np.ndarray]:
    """Each obstacle's outline from the pixels in and around its occupied cells (see the module's
    description).

    Parameters
    ----------
    gray : ndarray of shape (H, W), uint8
        The frame, in the camera's present view.
    occupied : ndarray of shape (rows, cols), bool
        The occupied cells, ``[row, col]``.
    reference : FootprintReference
        From :func:`footprint_reference` for the calibration.
    camera : CameraMotion, optional
        Calibration pixels -> frame pixels; None or unmoved: the frame is in the calibration's view.
    reach : float
        How many cells beyond the occupied ones an obstacle is looked for (1: their neighbours).
    margin : int
        Pixels of the small image (4 px each) the found region is grown by.
    texture_seed : float
        Texture level marking an obstacle's print inside an occupied cell (0: none).
    neck : int
        Side (small pixels) of the opening that parts pieces before their convex hulls (0: no hulls).
    support : float
        Share of changed pixels a piece outside the occupied cells needs to stay (0: every piece stays).
    debug : dict, optional
        Filled with the intermediate images (for inspection and tests).

    Returns
    -------
    list of ndarray (K, 2), float64
        Outlines ``(x, y)`` in calibration pixels.
    """
    ref = reference
    occupied = np.asarray(occupied, bool)
    rows, cols = ref.cell_quads.shape[:2]
    if occupied.shape != (rows, cols):
        raise InputError(f"occupied: expected shape {(rows, cols)}, got {occupied.shape}")
    if not occupied.any():
        return []
    s = ref.scale
    h, w = ref.reference.shape
    # where to look: the occupied cells and their neighbours (reach > 1: further)
    k = max(int(np.ceil(reach)), 0)
    near = cv2.dilate(occupied.astype(np.uint8), np.ones((2 * k + 1, 2 * k + 1), np.uint8)) > 0
    # the window: the ROI's bounding box and a pixel more (cv2.boundingRect reads the mask at
    # C speed; np.nonzero of the whole image cost more than the ROI's fill)
    near_cells = np.zeros((h, w), np.uint8)
    cv2.fillPoly(near_cells, list(ref.quads_fixed[near]), 1, cv2.LINE_8, shift=4)
    bx, by, bw, bh = cv2.boundingRect(near_cells)
    x0, y0 = max(bx - 1, 0), max(by - 1, 0)
    x1, y1 = min(bx + bw + 1, w), min(by + bh + 1, h)
    win = (slice(y0, y1), slice(x0, x1))
    roi = near_cells[win] > 0
    occ_cells = np.zeros((y1 - y0, x1 - x0), np.uint8)
    # (the offset is in the points' fixed point, like them)
    cv2.fillPoly(occ_cells, list(ref.quads_fixed[occupied]), 1, cv2.LINE_8, shift=4, offset=(-16 * x0, -16 * y0))
    occ = occ_cells > 0
    # a movement under a quarter pixel is under 1/16 of a small pixel: not worth a warp
    camera = CameraMotion.none() if camera is None else camera
    moved = camera.moved
    warp = moved and camera.max_movement_px >= 0.25
    if warp:
        frame = _in_calibration(gray, camera, s, (x0, y0, x1, y1))
    else:
        # the window's blocks only: the same block means as the whole frame's
        frame = _downsample(gray[y0 * s:y1 * s, x0 * s:x1 * s], s, (y1 - y0, x1 - x0))
    # the symbols' ink painted with the floor around it, on a logarithmic scale
    ink = ref.ink[win]
    painted = cv2.blur(frame * ref.floor_weight[win], (ref.paint, ref.paint)) / ref.floor_weight_sum[win]
    level = np.where(ink, painted, frame)
    logl = cv2.log(np.maximum(level, np.float32(1)))
    smooth = cv2.blur(logl, (3, 3))
    # the ROI's typical level (a sample's median: the scale only has to put the floor mid-range)
    centre = float(np.median(smooth[roi][::7]))
    image = np.clip(128.0 + LOG_LEVELS * (smooth - centre), 0, 255).astype(np.uint8)
    markers = np.zeros(frame.shape, np.int32)
    markers[~roi] = 1
    # free symbols' ink and the floor just around their outlines
    free = ~occupied.ravel()
    fi, fj = ref.floor_seed_ij[:, free[ref.floor_seed_cell]]
    _mark(markers, fi, fj, (x0, y0), 1)
    # occupied cells' outlines: runs of hidden points (obstacle), runs of visible ones (floor)
    occ_idx = np.flatnonzero(occupied.ravel())
    px, py = ref.probe_x[occ_idx], ref.probe_y[occ_idx]
    if moved:
        q = camera.to_frame(np.stack([px, py], axis=-1))
        fx, fy = q[..., 0].astype(np.float32), q[..., 1].astype(np.float32)
    else:
        fx, fy = px, py
    kept = edge_kept(gray, fx, fy, ref.factors[occ_idx])
    visible, hidden = _runs(kept, SEED_RUN), _runs(~kept, SEED_RUN)
    pi, pj = ref.probe_ij[:, occ_idx]
    _mark(markers, pi[:, 0][visible], pj[:, 0][visible], (x0, y0), 1)
    _mark(markers, pi[:, 1][visible], pj[:, 1][visible], (x0, y0), 1)
    # an obstacle's print: texture the floor does not have, inside occupied cells
    if texture_seed > 0:
        raw = cv2.log(np.maximum(frame, np.float32(1)))
        texture = cv2.blur(np.abs(raw - cv2.blur(raw, (3, 3))), (5, 5))
        printed = ((texture > texture_seed) & roi & ~ref.near_ink[win] & (markers == 0)).astype(np.uint8)
        # wear leaves texture too, in thin lines (tyre marks, scratches); an obstacle's print is
        # an area: an opening keeps areas only
        # an area: an opening keeps areas only, drawn 3 pixels in from where texture was measured
        # (the texture's 5 x 5 mean reaches 2 pixels past the print, its 3 x 3 difference one more)
        printed = _opened(printed, PRINT_OPEN, PRINT_OPEN - 6)
        # a printed area that reaches into an occupied cell, all of it: the print runs on where
        # the obstacle reaches beyond its cells
        # (in the printed areas' box: a lookup over the whole window cost more than the rest)
        px0, py0, pw, ph = cv2.boundingRect(printed)
        if pw:
            box = (slice(py0, py0 + ph), slice(px0, px0 + pw))
            n, labels = cv2.connectedComponents(printed[box], connectivity=8)
            inside = np.zeros(n, bool)
            inside[labels[occ[box] & (printed[box] > 0)]] = True
            inside[0] = False
            if inside.any():
                markers[box][inside[labels]] = 2
    _mark(markers, pi[:, 0][hidden], pj[:, 0][hidden], (x0, y0), 2)
    # ... and beyond the hidden stretch, off the painted ink: the obstacle that hides a stretch
    # of a symbol's edge stands on the floor beside it
    _mark(markers, pi[:, 2][hidden], pj[:, 2][hidden], (x0, y0), 2)
    seeds = markers.copy()
    if debug is not None:
        debug.update(window=(x0, y0, x1, y1), image=image, seeds=seeds, roi=roi)
    cv2.watershed(cv2.merge([image, image, image]), markers)
    region = _filled(markers == 2)
    if support > 0:
        region = _supported(region, occ, seeds == 1, frame, ref.log_reference[win],
                            texture if texture_seed > 0 else None, support)
    if neck > 0:
        region = _hulls(region, neck, seeds == 1)
    if margin > 0:
        region = cv2.dilate(region.astype(np.uint8), np.ones((2 * margin + 1, 2 * margin + 1), np.uint8)) > 0
    region &= roi & ref.grid_area[win]
    if debug is not None:
        debug.update(labels=markers, region=region)
    contours, _ = cv2.findContours(region.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    outlines: list[np.ndarray] = []
    for c in contours:
        # 0.7 of a small pixel: the margin's pixel keeps the outline outside what was found
        c = cv2.approxPolyDP(c, 0.7, True) if len(c) > 4 else c
        if len(c) < 3:
            c = _box(c)
        outlines.append(_full(c[:, 0, :].astype(np.float64) + (x0, y0), s))
    return outlines


def _supported(region: np.ndarray, occ: np.ndarray, floor: np.ndarray, frame: np.ndarray, log_reference: np.ndarray,
               texture: np.ndarray | None, share: float) -> np.ndarray:
    """``region`` without the pieces outside the occupied cells ``occ`` that look like the floor:
    a piece stays when at least ``share`` of its pixels differ from the reference by more than
    :data:`CHANGE_LEVEL` of the light around them (measured on the floor seeds ``floor``) or show
    an obstacle's print (``texture`` above :data:`TEXTURE_SEED`).

    Beyond its cells an obstacle is found by the pixels alone, and where they say nothing (a white
    box on a floor the light saturates) the watershed's regions meet anywhere.
    """
    outside = region & ~occ
    bx, by, bw, bh = cv2.boundingRect(outside.view(np.uint8))
    if bw == 0:
        return region
    pieces = outside[by:by + bh, bx:bx + bw].view(np.uint8)
    n, labels = cv2.connectedComponents(pieces, connectivity=8)
    if n <= 1:
        return region
    # the pieces' pixels only: the light around them is summed from integral images (box filters
    # of the whole box cost three times as much, for the few pixels the pieces hold)
    jj, ii = cv2.findNonZero(pieces).reshape(-1, 2).T
    piece = labels[ii, jj]
    h, w = region.shape
    r = 15  # the light is measured over 31 x 31 pixels
    y0, y1 = max(by - r, 0), min(by + bh + r, h)
    x0, x1 = max(bx - r, 0), min(bx + bw + r, w)
    box = (slice(y0, y1), slice(x0, x1))
    ratio = cv2.log(np.maximum(frame[box], np.float32(1))) - log_reference[box]
    ii, jj = ii + (by - y0), jj + (bx - x0)
    seeds = floor[box]
    if seeds.any():
        top, bottom = np.maximum(ii - r, 0), np.minimum(ii + r + 1, y1 - y0)
        left, right = np.maximum(jj - r, 0), np.minimum(jj + r + 1, x1 - x0)

        def summed(image: np.ndarray) -> np.ndarray:
            s = cv2.integral(image, sdepth=cv2.CV_64F)
            return s[bottom, right] - s[top, right] - s[bottom, left] + s[top, left]

        light = summed(ratio * seeds) / np.maximum(summed(seeds.view(np.uint8)), (2 * r + 1) ** 2 * 1e-3)
    else:
        light = np.float64(np.median(ratio[::3, ::3]))
    changed = np.abs(ratio[ii, jj] - light) > CHANGE_LEVEL
    if texture is not None:
        changed |= texture[box][ii, jj] > TEXTURE_SEED
    counts = np.bincount(piece, minlength=n)
    hits = np.bincount(piece[changed], minlength=n)
    drop = hits < share * counts
    drop[0] = False
    if not drop.any():
        return region
    out = region.copy()
    part = out[by:by + bh, bx:bx + bw]
    for label in np.flatnonzero(drop):  # few pieces: a comparison each costs less than a lookup
        part &= labels != label
    return out


def _opened(mask: np.ndarray, erode: int, dilate: int) -> np.ndarray:
    """``mask`` (uint8) eroded by a disc ``erode`` wide, then dilated by one ``dilate`` wide; the
    work is done in the box around the set pixels only (a disc is no separable kernel: it costs
    its area per pixel, and printed areas are few)."""
    x, y, bw, bh = cv2.boundingRect(mask)
    out = np.zeros_like(mask)
    if bw == 0:
        return out
    h, w = mask.shape
    pad = erode + dilate
    y0, y1, x0, x1 = max(y - pad, 0), min(y + bh + pad, h), max(x - pad, 0), min(x + bw + pad, w)
    out[y0:y1, x0:x1] = cv2.dilate(cv2.erode(mask[y0:y1, x0:x1], _disc(erode)), _disc(dilate))
    return out


def _disc(side: int) -> np.ndarray:
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (side, side))


def _mark(markers: np.ndarray, i: np.ndarray, j: np.ndarray, origin: tuple[int, int], label: int) -> None:
    """Label the small image's pixels ``(i, j)`` (1-D, whole image) of the window at ``origin``
    (x0, y0) that ``markers`` covers."""
    if not len(i):
        return
    h, w = markers.shape
    i, j = i - origin[1], j - origin[0]
    ok = (j >= 0) & (j < w) & (i >= 0) & (i < h)
    markers[i[ok], j[ok]] = label


def _filled(mask: np.ndarray) -> np.ndarray:
    """``mask`` with its holes filled (the outer outlines' insides)."""
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    out = np.zeros(mask.shape, np.uint8)
    cv2.drawContours(out, contours, -1, 1, -1)
    return out > 0


def _hulls(mask: np.ndarray, neck: int, floor: np.ndarray) -> np.ndarray:
    """``mask`` with the bays of its pieces filled: a piece (after an opening with a disc ``neck``
    wide, which parts pieces touching at a corner or by a thin neck) is set in its convex hull, and
    each bay between them is filled unless it holds a floor seed (``floor``: a free symbol, a
    visible stretch of a symbol's edge) or is larger than :data:`BAY_SHARE` of the piece (the notch
    between two obstacles touching at a corner is floor)."""
    opened = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_OPEN, _disc(neck))
    contours, _ = cv2.findContours(opened, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    out = mask.copy()
    for c in contours:
        hull = cv2.convexHull(c)
        x, y, bw, bh = cv2.boundingRect(hull)
        box = (slice(y, y + bh), slice(x, x + bw))
        inside = np.zeros((bh, bw), np.uint8)
        cv2.fillConvexPoly(inside, hull - (x, y), 1)
        bays = (inside > 0) & ~mask[box]
        if not bays.any():
            continue
        n, labels = cv2.connectedComponents(bays.astype(np.uint8), connectivity=4)
        size = np.bincount(labels.ravel(), minlength=n)
        seeded = np.zeros(n, bool)
        seeded[labels[floor[box] & bays]] = True
        fill = (size <= BAY_SHARE * cv2.contourArea(c)) | ~seeded
        fill[0] = False
        out[box] |= fill[labels]
    return out


def _box(c: np.ndarray) -> np.ndarray:
    """A contour of one or two pixels as the square around them (3+ vertices)."""
    p = c[:, 0, :]
    lo, hi = p.min(axis=0), p.max(axis=0)
    return np.array([[lo], [[hi[0], lo[1]]], [hi], [[lo[0], hi[1]]]], dtype=np.int32)
