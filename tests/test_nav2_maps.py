"""nav2 maps read and written as ROS 2 map_server reads them (issue 18, items 2 and 4).

``map_server_values`` follows nav2_map_server's loadMapFromFile: trinary, scale and raw modes with
negate. The maps here are made by hand, with the values map_server gives worked out beside them;
the planner's obstacles are every cell map_server does not load as free."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import shapely
from shapely.geometry import box

from _outputs_fixtures import paper
from sbplan.detection import exports
from sbplan.errors import MapFormatError
from sbplan.planning import load_obstacles
from sbplan.planning.loaders import map_server_values


def write_map(folder, image, *, name="map.png", **fields):
    cv2.imwrite(str(folder / name), image)
    meta = {"image": name, "resolution": 0.5, "origin": "[1.0, 2.0, 0.0]", **fields}
    (folder / "map.yaml").write_text("".join(f"{k}: {v}\n" for k, v in meta.items()))
    return folder / "map.yaml"


def union(obstacles):
    return shapely.union_all(obstacles.polygons)


# An 6 x 8 map (rows x cols, row 0 on top) at 0.5 m, origin (1, 2): a 2 x 3 occupied block at
# rows 1-2, cols 1-3, an unknown strip in the right column, free elsewhere.
BLOCK = box(1.0 + 1 * 0.5, 2.0 + 3 * 0.5, 1.0 + 4 * 0.5, 2.0 + 5 * 0.5)
STRIP = box(1.0 + 7 * 0.5, 2.0, 1.0 + 8 * 0.5, 2.0 + 6 * 0.5)


def test_a_raw_map_is_its_own_values_not_the_trinary_formula(tmp_path):
    img = np.zeros((6, 8), np.uint8)   # raw 0: free
    img[1:3, 1:4] = 100                # raw 100: occupied
    img[:, 7] = 255                    # raw > 100: unknown
    got = load_obstacles(write_map(tmp_path, img, mode="raw", negate=0))
    assert got.bounds == (1.0, 2.0, 5.0, 5.0)
    assert union(got).symmetric_difference(shapely.union_all([BLOCK, STRIP])).area < 1e-12
    # negate does not apply to raw maps (map_server reads raw values before it)
    again = load_obstacles(write_map(tmp_path, img, mode="raw", negate=1))
    assert union(again).equals(union(got))


@pytest.mark.parametrize("negate", [0, 1])
def test_a_trinary_map_with_and_without_negate(tmp_path, negate):
    img = np.full((6, 8), 254, np.uint8)
    img[1:3, 1:4] = 0
    img[:, 7] = 205
    if negate:
        img = 255 - img  # negate: white occupied, black free
    fields = dict(mode="trinary", negate=negate, occupied_thresh=0.65, free_thresh=0.196)
    got = load_obstacles(write_map(tmp_path, img, **fields))
    assert union(got).symmetric_difference(shapely.union_all([BLOCK, STRIP])).area < 1e-12


def test_a_scale_map_transparent_cells_are_unknown_and_in_between_values_obstacles(tmp_path):
    bgra = np.full((6, 8, 4), 255, np.uint8)
    bgra[1:3, 1:4, :3] = 128      # occ 0.498: between the thresholds -> a value in 1..99
    bgra[:, 7, 3] = 0             # transparent: unknown
    bgra[5, 0, :3] = 250          # occ 0.02 < free_thresh: free
    got = load_obstacles(write_map(tmp_path, bgra, mode="scale", negate=0, occupied_thresh=0.65, free_thresh=0.196))
    assert union(got).symmetric_difference(shapely.union_all([BLOCK, STRIP])).area < 1e-12


def test_map_server_values_by_hand():
    grey = np.array([[0, 128, 205, 254, 42, 101]], np.uint8)
    t = map_server_values(grey, mode="trinary", occupied_thresh=0.65, free_thresh=0.196)
    assert t.tolist() == [[100, -1, -1, 0, 100, -1]]  # 42: occ 0.835; 101: occ 0.604
    # nav2 map_saver's free_thresh 0.25 reads its own unknown (205, occ 0.196) as free
    assert map_server_values(grey, free_thresh=0.25)[0, 2] == 0
    s = map_server_values(grey, mode="scale", occupied_thresh=0.65, free_thresh=0.196)
    # 128: occ 0.4980, (0.4980 - 0.196) / 0.454 * 100 = 66.5 -> 67; 101: occ 0.6039 -> 89.8 -> 90
    assert s.tolist() == [[100, 67, 0, 0, 100, 90]]
    r = map_server_values(grey, mode="raw")
    assert r.tolist() == [[0, -1, -1, -1, 42, -1]]
    n = map_server_values(grey, mode="trinary", negate=True)
    assert n.tolist() == [[0, -1, 100, 100, 0, -1]]
    # colour: the mean of the channels; trinary averages the alpha channel in
    bgra = np.array([[[0, 0, 0, 255], [0, 0, 0, 0]]], np.uint8)
    assert map_server_values(bgra, mode="trinary").tolist() == [[100, 100]]  # shades 0.25 and 0
    assert map_server_values(bgra, mode="scale").tolist() == [[100, -1]]
    assert map_server_values(np.array([[[255, 255, 0]]], np.uint8)).tolist() == [[-1]]  # shade 2/3


@pytest.mark.parametrize("fields, fragment", [
    ({"mode": "ternary"}, "mode"),
    ({"free_thresh": 0.7, "occupied_thresh": 0.65}, "free_thresh"),
    ({"negate": "maybe"}, "negate"),
    ({"resolution": 0}, "resolution"),
])
def test_bad_nav2_fields_are_map_format_errors(tmp_path, fields, fragment):
    img = np.full((4, 4), 254, np.uint8)
    with pytest.raises(MapFormatError, match=fragment):
        load_obstacles(write_map(tmp_path, img, **fields))


def test_the_strip_beyond_the_floor_is_unknown_not_free(tmp_path):
    _, det, _ = paper()
    xmin, ymin, xmax, ymax = det.calibration.world_bounds()  # 4 x 3 m
    res = 0.07                                               # 57.1 x 42.9 pixels: a strip on two sides
    image, meta = exports.nav2_map(det, resolution=res)
    h, w = image.shape
    assert (w, h) == (58, 43)
    assert (image[:, -1] == 205).all() and (image[0, :] == 205).all()
    assert set(np.unique(image[1:, :-1])) == {0, 254}
    values = map_server_values(image, mode=meta["mode"], negate=bool(meta["negate"]),
                               occupied_thresh=meta["occupied_thresh"], free_thresh=meta["free_thresh"])
    assert (values[:, -1] == -1).all() and (values[0, :] == -1).all()
    # written and read back: the floor's free part is free, the strip an obstacle
    exports.write_nav2(tmp_path, det, resolution=res)
    got = load_obstacles(tmp_path / "map.yaml")
    gx0, gy0, gx1, gy1 = got.bounds
    assert (gx1, gy1) == pytest.approx((xmin + w * res, ymin + h * res))
    strip = box(xmin, ymin, gx1, gy1).difference(box(xmin, ymin, xmin + (w - 1) * res, ymin + (h - 1) * res))
    assert strip.difference(union(got)).area < 1e-9
    # with a resolution that divides the floor there is no strip: every pixel is on the floor
    image, _ = exports.nav2_map(det, resolution=0.05)
    assert image.shape == (60, 80) and set(np.unique(image)) == {0, 254}
