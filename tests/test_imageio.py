"""Bad images get clear errors; good ones of any common kind become 8-bit grayscale."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from sbplan.errors import ImageError
from sbplan.imageio import as_gray, load_image, write_atomic, write_json


def test_colour_is_converted_and_16_bit_is_scaled():
    bgr = np.zeros((4, 5, 3), np.uint8)
    bgr[..., 2] = 255  # pure red in OpenCV's BGR order
    gray = as_gray(bgr)
    assert gray.shape == (4, 5) and gray.dtype == np.uint8
    assert gray[0, 0] == cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)[0, 0]
    sixteen = np.array([[0, 65535], [32768, 257]], np.uint16)
    assert as_gray(sixteen).tolist() == [[0, 255], [128, 1]]
    assert as_gray(np.array([[0.0, 1.0]])).tolist() == [[0, 255]]
    assert as_gray(np.array([[True, False]])).tolist() == [[255, 0]]


@pytest.mark.parametrize("bad, message", [
    ("not an image", "not an image"),
    (np.zeros((0, 5), np.uint8), "empty image"),
    (np.zeros((4, 4, 2), np.uint8), "channels"),
    (np.zeros((2, 2, 2, 2), np.uint8), "shape"),
    (np.zeros((3, 3), np.int64), "unsupported dtype"),
    (np.full((3, 3), 2.0), r"\[0, 1\]"),
    (np.array([[np.nan]]), "NaN"),
])
def test_bad_arrays_are_refused_clearly(bad, message):
    with pytest.raises(ImageError, match=message):
        as_gray(bad, name="scene")


def test_unreadable_files(tmp_path):
    with pytest.raises(ImageError, match="no such file"):
        load_image(tmp_path / "missing.png")
    junk = tmp_path / "junk.png"
    junk.write_bytes(b"this is not a png")
    with pytest.raises(ImageError, match="not an image"):
        load_image(junk)
    with pytest.raises(ImageError, match="folder"):
        load_image(tmp_path)


def _damaged_files(folder):
    """A rendered floor written as PNG and JPEG, then cut short or with bytes overwritten."""
    from sbplan.synth import FloorSpec, render_reference

    image = render_reference(FloorSpec(width=320, height=240, cols=4, rows=3), seed=0)
    png = cv2.imencode(".png", image)[1].tobytes()
    jpg = cv2.imencode(".jpg", image)[1].tobytes()
    overwritten = bytearray(png)
    overwritten[len(png) // 2:len(png) // 2 + 40] = b"x" * 40
    files = {"truncated.png": png[: len(png) // 2], "overwritten.png": bytes(overwritten),
             "truncated.jpg": jpg[: len(jpg) // 2]}
    for name, data in files.items():
        (folder / name).write_bytes(data)
    return [folder / name for name in files]


def test_damaged_files_give_our_one_line_and_nothing_from_opencv(tmp_path, capfd):
    from sbplan.cli import main

    for path in _damaged_files(tmp_path):
        with pytest.raises(ImageError, match=r"not an image OpenCV can read: (truncated|damaged) (PNG|JPEG)"):
            load_image(path)
        # OpenCV's "[ WARN:0@...]" and libpng's "libpng error: ..." went to stderr (the file
        # descriptor, which capfd reads) before our line
        capfd.readouterr()
        assert main(["calibrate", str(path), "-o", str(tmp_path / "c.json")]) != 0
        err = capfd.readouterr().err
        assert err.splitlines() == [f"sbplan: error: {path}: not an image OpenCV can read: "
                                    f"{err.split(': ')[-1].strip()}"], err
        assert "WARN" not in err and "libpng" not in err and "Corrupt" not in err


def test_opencv_log_level_is_restored_after_reading(tmp_path):
    log = cv2.utils.logging
    before = log.getLogLevel()
    ok = tmp_path / "ok.png"
    cv2.imwrite(str(ok), np.full((8, 8), 128, np.uint8))
    load_image(ok)
    assert log.getLogLevel() == before


def test_atomic_write_keeps_the_old_file_when_writing_fails(tmp_path):
    target = tmp_path / "calibration.json"
    write_json(target, {"good": 1})

    def explode(fh):
        fh.write(b'{"half":')
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError):
        write_atomic(target, explode)
    assert target.read_text() == '{\n  "good": 1\n}\n'
    assert [p.name for p in tmp_path.iterdir()] == ["calibration.json"], "no temporary file is left behind"


def test_written_files_are_readable_like_any_other(tmp_path):
    import stat

    path = write_json(tmp_path / "result.json", {"a": 1})
    assert stat.S_IMODE(path.stat().st_mode) == 0o644
    path.chmod(0o600)
    write_json(path, {"a": 2})
    assert stat.S_IMODE(path.stat().st_mode) == 0o600, "a replaced file keeps its mode"


@pytest.mark.parametrize("seed", range(6))
def test_halve_is_opencv_area_averaging(seed):
    # the compiled halving gives INTER_AREA's values (it is taken for speed only), on whole images
    # and on crops of larger ones, and sizes, types or layouts it does not fit go to INTER_AREA itself
    from sbplan.imageio import halve

    rng = np.random.default_rng(seed)
    h, w = 2 * int(rng.integers(1, 200)), 2 * int(rng.integers(1, 200))
    big = rng.integers(0, 256, (h + 7, w + 9), dtype=np.uint8)
    every = np.arange(256, dtype=np.uint8)[rng.permutation(256)].reshape(16, 16)  # every value, at every corner
    for image in (rng.integers(0, 256, (h, w), dtype=np.uint8), rng.integers(0, 256, (h + 1, w), dtype=np.uint8),
                  rng.random((h, w + 1)).astype(np.float32), np.full((h, w), 255, np.uint8),
                  big[3:3 + h, 5:5 + w], big[:h, :w].T, every, np.kron(every, np.ones((2, 2), np.uint8))[1:-1, 1:-1],
                  rng.integers(0, 256, (h, w, 3), dtype=np.uint8)):
        want = cv2.resize(image, (image.shape[1] // 2, image.shape[0] // 2), interpolation=cv2.INTER_AREA)
        got = halve(image)
        assert got.dtype == image.dtype and np.array_equal(got, want)
