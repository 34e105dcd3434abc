"""sbplan bench match: generated silhouettes, Bullseye scoring, CLI output and errors."""

import json

import numpy as np
import pytest

from sbplan.bench.match import bullseye, chance_level
from sbplan.bench.silhouettes import load_silhouettes, make_silhouettes
from sbplan.cli import main
from sbplan.errors import ImageError, InputError
from sbplan.imageio import load_image


@pytest.fixture(scope="module")
def silhouettes(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sil")
    make_silhouettes(folder, classes=8, per_class=6, seed=3, size=96)
    return folder


def test_generator_writes_labelled_reproducible_sets(silhouettes, tmp_path):
    files = sorted(silhouettes.glob("*.png"))
    assert len(files) == 48
    data = load_silhouettes(silhouettes)
    assert len(set(data.labels)) == 8 and all(data.labels.count(c) == 6 for c in set(data.labels))
    # both polarities occur, and the loader finds a sizeable shape in each
    corners = [load_image(p)[0, 0] for p in files]
    assert 0 in corners and 255 in corners
    assert all(len(o) > 40 for o in data.outlines)
    again = make_silhouettes(tmp_path, classes=8, per_class=6, seed=3, size=96)
    assert all(np.array_equal(load_image(a), load_image(b)) for a, b in zip(sorted(again), files))
    with pytest.raises(InputError, match="per_class"):
        make_silhouettes(tmp_path, classes=3, per_class=1)


def test_generated_sets_have_mpeg7s_hard_cases(tmp_path):
    import cv2

    files = make_silhouettes(tmp_path, classes=12, per_class=10, seed=0, size=128)
    names = {f.stem.rsplit("-", 1)[0] for f in files}
    assert any(n.startswith("animal") for n in names) and any(n.startswith("sibling") for n in names)
    holes = 0
    for f in files:
        img = load_image(f)
        shape = (img > 127) if img[0, 0] < 128 else (img < 128)
        _, hierarchy = cv2.findContours(shape.astype(np.uint8), cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
        holes += int((hierarchy[0][:, 3] >= 0).any())
    assert holes >= 10  # about 3 in 10 instances have holes punched in


def test_bullseye_convention():
    labels = ["a", "a", "b", "b"]
    perfect = np.array([[0, 1, 5, 5], [1, 0, 5, 5], [5, 5, 0, 1], [5, 5, 1, 0]], float)
    assert bullseye(perfect, labels).tolist() == [1.0, 1.0, 1.0, 1.0]
    # with 2 x class size = all 4 shapes retrieved, every query scores 1: the window is 2C
    worst = np.array([[0, 9, 1, 1], [9, 0, 1, 1], [1, 1, 0, 9], [1, 1, 9, 0]], float)
    assert bullseye(worst, labels).tolist() == [1.0, 1.0, 1.0, 1.0]
    labels3 = ["a", "a", "b", "b", "c", "c"]
    d = np.full((6, 6), 5.0)
    np.fill_diagonal(d, 0)
    d[0, 2] = d[0, 3] = d[0, 4] = 1  # query 0 ranks other classes first: only itself in its top 4
    assert bullseye(d, labels3)[0] == 0.5
    assert 0 < chance_level(labels3) < 1


def test_fourier_beats_chance_by_a_wide_margin(silhouettes, capsys):
    assert main(["bench", "match", str(silhouettes), "--json", "--repeat", "1"]) == 0
    report = json.loads(capsys.readouterr().out)
    rows = {r["matcher"]: r for r in report["results"]}
    assert {"fourier", "centroid-distance", "hu-moments"} <= set(rows)
    chance = report["chance_bullseye_percent"]
    assert chance < 40
    assert rows["fourier"]["bullseye_percent"] >= chance + 40
    for r in rows.values():
        assert r["bullseye_percent"] > chance
        assert r["describe_us"] > 0 and r["distance_matrix_ns_per_pair"] > 0


def test_hard_set_no_longer_reads_near_100_percent(tmp_path, capsys):
    make_silhouettes(tmp_path, classes=12, per_class=10, seed=0, size=128)
    assert main(["bench", "match", str(tmp_path), "--json", "--repeat", "1", "-q",
                 "--matchers", "fourier,centroid-distance"]) == 0
    report = json.loads(capsys.readouterr().out)
    for r in report["results"]:
        assert report["chance_bullseye_percent"] + 30 < r["bullseye_percent"] < 90, r


def test_several_sets_progress_and_comparisons(silhouettes, tmp_path, capsys):
    made = tmp_path / "made"
    assert main(["bench", "match", str(silhouettes), "--make", str(made), "--classes", "3", "--per-class", "3",
                 "--size", "64", "--matchers", "fourier", "--repeat", "2", "--json"]) == 0
    captured = capsys.readouterr()
    sets = json.loads(captured.out)["sets"]
    assert [s["shapes"] for s in sets] == [48, 9]
    row = sets[0]["results"][0]
    assert row["comparisons_per_second"] == pytest.approx(48 * 48 / row["distance_matrix_s"], rel=0.01)
    assert 1 <= row["distance_matrix_runs"] <= 2
    assert f"bench match: {silhouettes}: 48 shapes, 8 classes" in captured.err
    assert "[1/1] fourier" in captured.err and "distance_matrix 48 x 48" in captured.err
    assert main(["bench", "match", str(silhouettes), "--matchers", "fourier", "--repeat", "1", "-q"]) == 0
    captured = capsys.readouterr()
    assert captured.err == "" and "comparisons/s" in captured.out


def test_table_output_and_make(tmp_path, capsys):
    out = tmp_path / "made"
    assert main(["bench", "match", "--make", str(out), "--classes", "3", "--per-class", "3",
                 "--size", "64", "--matchers", "fourier", "--repeat", "1",
                 "--approximator", "douglas-peucker"]) == 0
    text = capsys.readouterr().out
    assert "| fourier" in text and "Bullseye" in text and "douglas-peucker" in text
    assert len(list(out.glob("*.png"))) == 9


def test_clear_errors(tmp_path, capsys):
    def error(args):
        code = main(["bench", "match", *args])
        return code, capsys.readouterr().err

    code, err = error([str(tmp_path / "missing")])
    assert code != 0 and err.startswith("sbplan: error:") and "no such folder" in err
    code, err = error([str(tmp_path)])
    assert code != 0 and "no PNG" in err
    (tmp_path / "noclass.png").write_bytes(b"")
    code, err = error([str(tmp_path)])
    assert code != 0 and "has no class" in err
    (tmp_path / "noclass.png").unlink()
    (tmp_path / "star-1.png").write_bytes(b"not a png")
    code, err = error([str(tmp_path)])
    assert code != 0 and "star-1.png" in err and "not an image" in err
    code, err = error([])
    assert code != 0 and "--make" in err
    with pytest.raises(ImageError, match="no shape"):
        (tmp_path / "star-1.png").unlink()
        from sbplan.imageio import write_image
        write_image(tmp_path / "blank-1.png", np.zeros((20, 20), np.uint8))
        load_silhouettes(tmp_path)
