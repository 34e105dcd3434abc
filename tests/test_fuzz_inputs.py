"""Malformed inputs give an SbplanError, never another exception (issue 18, "What must hold").

Hypothesis mutates real files sbplan wrote (a calibration, a detection result, GeoJSON local and
georeferenced, a nav2 map.yaml and its image): a member replaced by any JSON value, deleted, or
the text cut short; and feeds detect arrays and image files of random sizes, dtypes and channels,
and truncated or corrupted image files. Whatever loads must then work: a loaded calibration
detects, loaded obstacles plan. Examples are derandomized (tests/conftest.py) and few, so the
suite stays fast; ``--hypothesis-profile=explore`` with ``SBPLAN_FUZZ_EXAMPLES=2000`` searches
afresh and long.
"""

from __future__ import annotations

import copy
import json
import math
import os

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from _outputs_fixtures import paper
from sbplan.detection import Detector, exports
from sbplan.detection.calibration import load_calibration
from sbplan.errors import SbplanError
from sbplan.imageio import load_image, write_json
from sbplan.planning import PlanningMap, load_obstacles
from sbplan.workspace import Georeference

#: Few examples on every run (the suite stays fast); SBPLAN_FUZZ_EXAMPLES=2000 with
#: --hypothesis-profile=explore for a long search.
FUZZ = settings(max_examples=int(os.environ.get("SBPLAN_FUZZ_EXAMPLES", 60)), deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                       HealthCheck.too_slow])

json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-10**6, 10**6) | st.sampled_from([0, 1, -1, 2**63, 1e308])
    | st.floats(allow_nan=True, allow_infinity=True) | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner, max_size=3),
    max_leaves=12)


def paths(doc, depth=4, prefix=()):
    """Every member's path down to ``depth`` (the first two items of each list)."""
    out = [prefix] if prefix else []
    if depth == 0:
        return out
    if isinstance(doc, dict):
        for k, v in doc.items():
            out += paths(v, depth - 1, prefix + (k,))
    elif isinstance(doc, list):
        for i, v in enumerate(doc[:2]):
            out += paths(v, depth - 1, prefix + (i,))
    return out


@st.composite
def mutated_text(draw, doc: dict) -> str:
    """The document's JSON with one member replaced or deleted, or its text cut short."""
    how = draw(st.sampled_from(["replace", "delete", "cut", "replace-root"]))
    if how == "replace-root":
        return json.dumps(draw(json_values))
    if how == "cut":
        text = json.dumps(doc)
        return text[: draw(st.integers(0, len(text) - 1))]
    doc = copy.deepcopy(doc)
    path = draw(st.sampled_from(paths(doc)))
    parent = doc
    for key in path[:-1]:
        parent = parent[key]
    if how == "delete":
        del parent[path[-1]]
    else:
        parent[path[-1]] = draw(json_values)
    return json.dumps(doc)


def only_sbplan_errors(call):
    """Run ``call``: it may succeed or raise an SbplanError; anything else fails the test."""
    try:
        return call()
    except SbplanError as exc:
        assert str(exc) and "\n" not in str(exc).strip(), repr(exc)  # one readable line
        return None


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    cal, det, image = paper()
    out = tmp_path_factory.mktemp("fuzz-src")
    cal.save(out / "calibration.json")
    write_json(out / "result.json", det.to_json())
    exports.write_geojson(out / "local.geojson", det)
    exports.write_geojson(out / "geo.geojson", det, georeference=Georeference(52.5, 13.4, 30.0))
    exports.write_nav2(out / "nav2", det)
    return out, image


def _plans(obstacles):
    """Loaded obstacles are usable: a map can be built on them (or refused as an SbplanError)."""
    if obstacles is not None and obstacles.polygons:
        only_sbplan_errors(lambda: PlanningMap(obstacles.polygons, robot_radius=0.1, bounds=obstacles.bounds))


@FUZZ
@given(data=st.data())
def test_malformed_calibration_files(files, tmp_path, data):
    folder, image = files
    doc = json.loads((folder / "calibration.json").read_text())
    (tmp_path / "cal.json").write_text(data.draw(mutated_text(doc)))
    cal = only_sbplan_errors(lambda: load_calibration(tmp_path / "cal.json"))
    if cal is not None:
        only_sbplan_errors(lambda: Detector(cal)(image))


@FUZZ
@given(data=st.data(), name=st.sampled_from(["result.json", "local.geojson", "geo.geojson"]))
def test_malformed_detection_json_and_geojson(files, tmp_path, data, name):
    folder, _ = files
    doc = json.loads((folder / name).read_text())
    target = tmp_path / name
    target.write_text(data.draw(mutated_text(doc)))
    _plans(only_sbplan_errors(lambda: load_obstacles(target)))


yaml_scalars = st.none() | st.booleans() | st.integers(-10**20, 10**20) | st.floats() | st.text(max_size=10) \
    | st.sampled_from(["trinary", "scale", "raw", "map.pgm", "[1, 2]", "[.nan, 0, 0]", "{a: 1}", "*x", "&y [1]"])


@FUZZ
@given(data=st.data())
def test_malformed_nav2_yaml(files, tmp_path, data):
    folder, _ = files
    lines = (folder / "nav2" / "map.yaml").read_text().splitlines()
    (tmp_path / "map.pgm").write_bytes((folder / "nav2" / "map.pgm").read_bytes())
    how = data.draw(st.sampled_from(["value", "drop", "cut", "garbage", "image"]))
    if how == "value":
        i = data.draw(st.integers(0, len(lines) - 1))
        key = lines[i].split(":")[0]
        lines[i] = f"{key}: {data.draw(yaml_scalars)}"
    elif how == "drop":
        del lines[data.draw(st.integers(0, len(lines) - 1))]
    elif how == "cut":
        text = "\n".join(lines)
        lines = [text[: data.draw(st.integers(0, len(text)))]]
    elif how == "garbage":
        lines = [data.draw(st.text(max_size=40))]
    else:  # the image cut short or bytes overwritten
        raw = bytearray((folder / "nav2" / "map.pgm").read_bytes())
        if data.draw(st.booleans()):
            raw = raw[: data.draw(st.integers(0, len(raw)))]
        else:
            for _ in range(data.draw(st.integers(1, 8))):
                raw[data.draw(st.integers(0, len(raw) - 1))] = data.draw(st.integers(0, 255))
        (tmp_path / "map.pgm").write_bytes(bytes(raw))
    (tmp_path / "map.yaml").write_text("\n".join(lines) + "\n")
    _plans(only_sbplan_errors(lambda: load_obstacles(tmp_path / "map.yaml")))


dtypes = st.sampled_from([np.uint8, np.uint16, np.int8, np.int16, np.int32, np.int64, np.float16, np.float32,
                          np.float64, np.bool_, np.complex64, object, "U2"])


@st.composite
def arrays(draw):
    cal, _, _ = paper()
    h, w = cal.image_shape
    if draw(st.booleans()):  # the calibration's size: the pipeline runs on it
        shape = (h, w)
    else:
        shape = (draw(st.integers(0, 40)), draw(st.integers(0, 40)))
    channels = draw(st.sampled_from([None, 1, 2, 3, 4, 5]))
    if channels is not None:
        shape = shape + (channels,)
    if draw(st.integers(0, 9)) == 0:
        shape = shape[:1]  # one-dimensional
    dtype = draw(dtypes)
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    values = rng.uniform(-0.5, 1.5, shape) * draw(st.sampled_from([1, 255, 65535]))
    if draw(st.booleans()):
        values = np.clip(values, 0, None)
    if draw(st.integers(0, 5)) == 0 and values.size:
        values.flat[0] = draw(st.sampled_from([math.nan, math.inf]))
    try:
        with np.errstate(invalid="ignore", over="ignore"):
            return values.astype(dtype)
    except (ValueError, OverflowError):
        return values


@FUZZ
@given(image=arrays())
def test_detect_on_random_arrays(image):
    cal, _, _ = paper()
    only_sbplan_errors(lambda: Detector(cal)(image))


@FUZZ
@given(data=st.data(), ext=st.sampled_from([".png", ".jpg", ".pgm", ".bmp", ".tiff"]))
def test_detect_on_truncated_and_corrupted_image_files(files, tmp_path, data, ext):
    folder, image = files
    cal, _, _ = paper()
    ok, buf = cv2.imencode(ext, image)
    raw = bytearray(buf.tobytes())
    how = data.draw(st.sampled_from(["cut", "flip", "empty", "text"]))
    if how == "cut":
        raw = raw[: data.draw(st.integers(0, len(raw) - 1))]
    elif how == "flip":
        for _ in range(data.draw(st.integers(1, 16))):
            raw[data.draw(st.integers(0, len(raw) - 1))] = data.draw(st.integers(0, 255))
    elif how == "empty":
        raw = bytearray()
    else:
        raw = bytearray(data.draw(st.text(max_size=30)).encode())
    path = tmp_path / f"scene{ext}"
    path.write_bytes(bytes(raw))
    frame = only_sbplan_errors(lambda: load_image(path))
    if frame is not None:
        only_sbplan_errors(lambda: Detector(cal)(frame))


@pytest.mark.parametrize("edit, fragment", [
    (lambda d: d["stages"].pop("approximator"), "stages.approximator"),
    (lambda d: d["symbol"]["polygons"].pop(), "outlines for a grid of 6 x 8"),
    (lambda d: d["symbol"].__setitem__("descriptor", []), "descriptor"),
    (lambda d: d["symbol"]["edge_contrast"].pop(), "edge_contrast"),
    (lambda d: d["grid"].__setitem__("homography", [[0, 0, 0]] * 3), "singular"),
])
def test_what_the_fuzzer_found_in_calibrations_is_refused_on_load(files, tmp_path, edit, fragment):
    """Edits of the kind the fuzzer found (a stage missing loaded, then failed detection with a
    KeyError): refused when the file is read."""
    folder, _ = files
    doc = json.loads((folder / "calibration.json").read_text())
    edit(doc)
    (tmp_path / "cal.json").write_text(json.dumps(doc))
    with pytest.raises(SbplanError, match=fragment):
        load_calibration(tmp_path / "cal.json")
