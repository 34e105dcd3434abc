"""Live watching (sbplan.live, ``sbplan watch``) on rendered streams read back through OpenCV.

The stream (sbplan.synth.sequence.demo_sequence) holds an obstacle that stays, one that shows for
less than the hysteresis, one that enters, slides a pitch and leaves, a person's shadow passing,
a camera bump, a dropped frame, an undecodable frame and a damaged one. It is written once as an
MJPG AVI and once as a folder of PNGs; every check compares the events with the stream's truth.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

import cv2
import numpy as np
import pytest
from shapely.geometry import LineString, Polygon, box

import sbplan
from sbplan.detection import Detector
from sbplan.errors import InputError
from sbplan.live import (EXIT_CODES, CellHysteresis, FrameReader, Hysteresis, IterableSource, ObstacleTracker,
                         Read, Source, SourceError, VideoSource, Watcher, events_schema)
from sbplan.live.reader import Frame, Notice
from sbplan.live.watcher import THUMB_BLOCK, changed_boxes, refreshed
from sbplan.synth import FloorSpec
from sbplan.synth.sequence import demo_sequence, read_truth, write_sequence

H = 3  # hysteresis, frames
FLOOR = FloorSpec(width=480, height=360, cols=8, rows=6)
N_FRAMES = 36
START, GOAL = (0.25, 1.25), (3.75, 1.25)  # across row 3, where obstacle 2 slides
RADIUS = 0.1
EVENTS_SEEN: list[dict] = []  # every event of this module's watches, for the schema test


@pytest.fixture(scope="module")
def stream(tmp_path_factory):
    """The demo stream as AVI and as a folder, its truth and a calibration on its reference."""
    root = tmp_path_factory.mktemp("stream")
    spec = demo_sequence(FLOOR, n_frames=N_FRAMES, hysteresis=H)
    avi = write_sequence(root / "avi", FLOOR, spec, seed=3, kind="avi")
    folder = write_sequence(root / "folder", FLOOR, spec, seed=3, kind="folder")
    cal = sbplan.calibrate(root / "avi" / "reference.png", cell_size=0.5)
    cal_path = cal.save(root / "calibration.json")
    return {"spec": spec, "avi": avi, "folder": folder, "truth": read_truth(root / "avi"), "cal": cal,
            "cal_path": cal_path, "root": root}


def run(watcher: Watcher) -> list[dict]:
    events = list(watcher.events())
    EVENTS_SEEN.extend(events)
    return events


@pytest.fixture(scope="module")
def avi_events(stream):
    return run(Watcher(stream["avi"], stream["cal"], hysteresis=H, start=START, goal=GOAL, robot_radius=RADIUS))


@pytest.fixture(scope="module")
def folder_events(stream):
    return run(Watcher(stream["folder"], stream["cal"], hysteresis=H, start=START, goal=GOAL, robot_radius=RADIUS))


def frames_of(stream, kind: str) -> list[dict]:
    """The truth of every frame the source delivers, in order, each with its source number."""
    out = []
    for t in stream["truth"]:
        if t["written"] is None or t["corrupt"]:
            continue
        number = t["written"] if kind == "avi" else t["frame"]
        out.append(dict(t, number=number))
    return out


def states_by_frame(events: list[dict]) -> dict[int, dict[int, set]]:
    """Obstacle id -> cells after each frame that had obstacle events, replayed from the events."""
    now: dict[int, set] = {}
    out = {}
    for e in events:
        if e["type"].startswith("obstacle_"):
            ob = e["obstacle"]
            if e["type"] == "obstacle_left":
                del now[ob["id"]]
            else:
                now[ob["id"]] = {tuple(c) for c in ob["cells"]}
            out[e["frame"]] = {k: set(v) for k, v in now.items()}
    return out


def state_at(states: dict, frame: int) -> dict[int, set]:
    earlier = [f for f in states if f <= frame]
    return states[max(earlier)] if earlier else {}


@pytest.mark.parametrize("kind", ["avi", "folder"])
def test_lasting_obstacles_reported_with_their_cells_and_blips_never(stream, avi_events, folder_events, kind):
    events = avi_events if kind == "avi" else folder_events
    frames = frames_of(stream, kind)
    states = states_by_frame(events)
    blip = {tuple(c) for t in stream["truth"] for c in t["tracks"].get("1", [])}
    assert blip, "the stream has a blip obstacle"
    checked = 0
    for i, t in enumerate(frames):
        reported = state_at(states, t["number"])
        cells = set().union(*reported.values()) if reported else set()
        assert not cells & blip, f"frame {t['number']}: the blip shorter than the hysteresis was reported"
        window = frames[max(i - H + 1, 0):i + 1]
        # every cell reported was really covered (occupied or a sliver) in at least one of the last frames
        for cell in cells:
            assert any(w["cells"][cell[0]][cell[1]] != 0 for w in frames[max(i - 2 * H, 0):i + 1]), \
                f"frame {t['number']}: cell {cell} reported but free"
        if len(window) < H or any(w["damaged"] for w in window):
            continue
        for track in ("0", "2"):
            # a track whose cells stayed the same over the last H frames is reported with exactly them
            seen = [frozenset(map(tuple, w["tracks"].get(track, []))) for w in window]
            if seen[0] and len(set(seen)) == 1:
                assert any(seen[0] <= c for c in reported.values()), \
                    f"frame {t['number']}: obstacle {track} {sorted(seen[0])} not reported ({reported})"
                assert any(c == seen[0] for c in reported.values()), \
                    f"frame {t['number']}: obstacle {track}'s cells {sorted(seen[0])}, reported {reported}"
                checked += 1
    assert checked > N_FRAMES // 2


@pytest.mark.parametrize("kind", ["avi", "folder"])
def test_ids_stay_while_an_obstacle_stays(stream, avi_events, folder_events, kind):
    events = avi_events if kind == "avi" else folder_events
    kinds = [e["type"] for e in events if e["type"].startswith("obstacle_")]
    # obstacle 0 (stays), obstacle 2 (enters, slides, leaves): two appear, the slider moves and leaves
    assert kinds.count("obstacle_appeared") == 2, kinds
    assert kinds.count("obstacle_left") == 1, kinds
    appeared = [e["obstacle"]["id"] for e in events if e["type"] == "obstacle_appeared"]
    moved = {e["obstacle"]["id"] for e in events if e["type"] == "obstacle_moved"}
    left = [e["obstacle"]["id"] for e in events if e["type"] == "obstacle_left"]
    assert len(set(appeared)) == 2
    assert moved and moved <= set(appeared) and left[0] in moved
    slid = {tuple(c) for e in events if e["type"] == "obstacle_moved" for c in e["obstacle"]["cells"]}
    assert {(3, 1), (3, 2)} <= slid


@pytest.mark.parametrize("kind", ["avi", "folder"])
def test_route_events_never_cross_a_present_obstacle(stream, avi_events, folder_events, kind):
    events = avi_events if kind == "avi" else folder_events
    cal = stream["cal"]
    frames = {t["number"]: i for i, t in enumerate(frames_of(stream, kind))}
    ordered = frames_of(stream, kind)
    routes = [e for e in events if e["type"] == "route"]
    assert len(routes) >= 3  # first plan, around the slider, after it left
    assert any(len(e["route"]["waypoints_m"]) > 2 for e in routes), "some route bends around an obstacle"
    now: dict[int, np.ndarray] = {}
    for e in events:
        if e["type"] in ("obstacle_appeared", "obstacle_moved"):
            now[e["obstacle"]["id"]] = np.asarray(e["obstacle"]["mar_m"])
        elif e["type"] == "obstacle_left":
            del now[e["obstacle"]["id"]]
        elif e["type"] == "route":
            assert e["status"] in ("exact", "approximate"), e
            line = LineString(e["route"]["waypoints_m"])
            for mar in now.values():  # the obstacles the route was planned around
                assert line.distance(Polygon(mar)) >= RADIUS - 1e-6
            # ... and the truth: no cell covered over the last H frames lies on the route
            i = frames[e["frame"]]
            for track in ("0", "2"):
                window = [set(map(tuple, w["tracks"].get(track, []))) for w in ordered[max(i - H + 1, 0):i + 1]]
                for r, c in set.intersection(*window) if len(window) == H else set():
                    (x0, y0), (x1, y1) = cal.workspace.lattice_to_world(np.array([[c - 0.5, r + 0.5],
                                                                                  [c + 0.5, r - 0.5]]), cal.grid.rows)
                    assert not line.intersects(box(x0, y0, x1, y1).buffer(-1e-3)), \
                        f"route at frame {e['frame']} crosses cell {(r, c)} of obstacle {track}"


def test_corrupt_frames_are_skipped_and_counted(stream, avi_events, folder_events):
    n = len(stream["truth"])
    for events, missing in ((avi_events, 0), (folder_events, 1)):
        end = events[-1]
        assert end["type"] == "ended" and end["reason"] == "ended" and end["exit_code"] == 0
        s = end["stats"]
        assert s["frames_corrupt"] == 1
        assert s["frames_missing"] == missing  # the folder's numbering shows the dropped frame
        assert s["frames_processed"] == n - 2 and s["frames_dropped"] == 0


def test_camera_bump_is_reported(stream, avi_events):
    bump_frame, (dx, dy, rot, _) = stream["spec"].bump
    bumped = next(t["written"] for t in stream["truth"] if t["frame"] >= bump_frame and t["written"] is not None)
    moved = [e for e in avi_events if e["type"] == "camera_moved"]
    assert [e["frame"] for e in moved] == [bumped]
    cam = moved[0]["camera"]
    assert moved[0]["registered"] and abs(cam["rotation_deg"] - rot) < 0.05
    assert np.hypot(cam["shift_px"][0] - dx, cam["shift_px"][1] - dy) < 0.5


# -- changed in part: only the cells near the change detected again -------------------------------------
def test_a_local_change_gives_the_cells_a_whole_detection_gives(stream):
    """On each changed frame of the stream, Detector.find_cells_local (as the watch calls it) gives
    the cells find_cells gives; the camera bump goes through find_cells."""
    cal = stream["cal"]
    folder = stream["root"] / "folder" / stream["folder"]
    frames = [cv2.imread(str(folder / f"frame-{t['frame']:05d}.png"), cv2.IMREAD_GRAYSCALE)
              for t in frames_of(stream, "folder")]
    bump_frame = stream["spec"].bump[0]
    bumped = next(i for i, t in enumerate(frames_of(stream, "folder")) if t["frame"] >= bump_frame)
    local, whole = Detector(cal), Detector(cal)
    thumb = None
    compared, paths = 0, {}
    for i, image in enumerate(frames):
        expected = whole.find_cells(image)
        small = cv2.resize(image, (image.shape[1] // THUMB_BLOCK, image.shape[0] // THUMB_BLOCK),
                           interpolation=cv2.INTER_LINEAR)
        changed = None if thumb is None else cv2.compare(cv2.absdiff(small, thumb), 10, cv2.CMP_GT)
        if changed is None or not changed.any():
            if changed is None:
                local.find_cells(image)
                thumb = small
            continue
        before = local.motion
        got = local.find_cells_local(image, changed_boxes(changed, THUMB_BLOCK))
        paths[i] = "whole" if got is None else "local"
        if got is None:
            local.find_cells(image)
            thumb = small
            continue
        thumb = refreshed(thumb, small, local.kept_reads(), THUMB_BLOCK)
        compared += 1
        assert np.array_equal(got.occupied, expected.occupied), i
        assert (got.symbols_found, got.symbols_rescued) == (expected.symbols_found, expected.symbols_rescued)
        # the same centres, maybe in another order; the pose is the last frame's
        for a, b in ((got.matched_centres_px, expected.matched_centres_px),
                     (got.candidates_px, expected.candidates_px)):
            assert a.shape == b.shape
            assert np.allclose(np.sort(a, axis=0), np.sort(b, axis=0), atol=0.5)
        assert got.camera is before and local.motion is before
    # most changed frames are local ones (an obstacle, the shadow: 9 of 14 here); the bump is not
    assert compared > len(paths) / 2 and compared >= 8
    assert paths[bumped] == "whole"


def test_a_watch_reports_the_same_events_with_local_detection_or_whole(stream, folder_events):
    events = run(Watcher(stream["folder"], stream["cal"], hysteresis=H, start=START, goal=GOAL, robot_radius=RADIUS,
                         local=False))

    def summary(evs):
        out = []
        for e in evs:
            if e["type"] in ("stats", "ended", "started"):
                continue
            item = [e["type"], e["frame"]]
            if "obstacle" in e:
                item += [e["obstacle"]["id"], e["obstacle"]["cells"]]
            if e["type"] == "route":
                item += [e["status"], e["route"] and np.round(e["route"]["waypoints_m"], 6).tolist()]
            out.append(item)
        return out

    assert summary(events) == summary(folder_events)
    assert any(e["type"] == "route" for e in events) and any(e["type"] == "obstacle_moved" for e in events)
    local = folder_events[-1]["stats"]
    assert local["frames_local"] > 0 and events[-1]["stats"]["frames_local"] == 0
    assert local["frames_processed"] == events[-1]["stats"]["frames_processed"]


# -- the stream's faults --------------------------------------------------------------------------------
class PausingSource(Source):
    """A video file whose first capture blocks before frame ``at`` until ``go`` is set."""

    def __init__(self, path, at: int):
        self.inner = VideoSource(path)
        self.name, self.kind, self.live, self.fps = self.inner.name, "file", False, None
        self.at, self.go, self.paused = at, threading.Event(), threading.Event()
        self.opens = 0

    def open(self, after=None):
        self.opens += 1
        cap, first = self.inner.open(after), self.opens == 1
        outer = self

        class Cap:
            def read(self):
                if first and (cap.last if cap.last is not None else -1) + 1 == outer.at:
                    outer.paused.set()
                    outer.go.wait(30)
                return cap.read()

            def close(self):
                cap.close()

        return Cap()


def test_a_blocked_source_is_reported_stalled_within_its_timeout_and_reopened(stream):
    src = PausingSource(stream["avi"], at=10)
    watcher = Watcher(src, stream["cal"], hysteresis=H, stall_timeout=0.3, backoff=(0.01, 0.05))
    try:
        events = run(watcher)
    finally:
        src.go.set()  # the thread left behind in the blocked read returns (and discards its frame)
    kinds = [e["type"] for e in events]
    assert kinds.count("stalled") == 1 and kinds.count("reconnected") == 1
    stalled = events[kinds.index("stalled")]
    back = events[kinds.index("reconnected")]
    assert 0.3 <= stalled["since_last_frame_s"] < 0.3 + 2.0  # reported once the timeout passed
    assert back["reopened"] and back["frame"] == 10 and src.opens == 2
    end = events[-1]
    assert end["reason"] == "ended" and end["stats"]["frames_processed"] == len(frames_of(stream, "avi"))
    numbers = [e["frame"] for e in events if e["frame"] is not None]
    assert numbers == sorted(numbers)  # nothing from the thread left behind


@pytest.fixture(scope="module")
def paused_events(stream):
    """The events of a Python source that pauses after 3 of 6 frames until it is reported stalled."""
    frames = [cv2.imread(str(stream["folder"] / f"frame-{k:05d}.png"), 0) for k in range(6)]
    go = threading.Event()

    def feed():
        yield from frames[:3]
        go.wait(30)
        yield from frames[3:]

    watcher = Watcher(IterableSource(feed()), stream["cal"], hysteresis=H, stall_timeout=0.2, latest=False)
    events = []
    for e in watcher.events():
        events.append(e)
        if e["type"] == "stalled":
            go.set()
    EVENTS_SEEN.extend(events)
    return events


def test_a_paused_python_source_is_stalled_then_resumed(paused_events):
    events = paused_events
    kinds = [e["type"] for e in events]
    assert kinds.index("stalled") < kinds.index("reconnected")
    back = events[kinds.index("reconnected")]
    assert not back["reopened"] and back["frame"] == 3
    assert events[-1]["stats"]["frames_processed"] == 6


class FlakySource(Source):
    """Frames from a list; the first capture fails (lost) after ``lose_after`` frames, then the
    next ``refuse`` opens fail."""

    kind, live, fps = "camera", True, None

    def __init__(self, frames, lose_after: int, refuse: int):
        self.name = "flaky"
        self.frames, self.lose_after, self.refuse = frames, lose_after, refuse
        self.opens = 0
        self.given = 0

    def open(self, after=None):
        self.opens += 1
        if 1 < self.opens <= 1 + self.refuse:
            raise SourceError("flaky: cannot open")
        outer, first = self, self.opens == 1

        class Cap:
            def read(self):
                if first and outer.given == outer.lose_after:
                    return Read("lost")
                if outer.given >= len(outer.frames):
                    return Read("end")
                outer.given += 1
                return Read("frame", outer.frames[outer.given - 1])

            def close(self):
                pass

        return Cap()


def test_a_lost_source_is_reopened_with_backoff(stream):
    frames = [cv2.imread(str(stream["folder"] / f"frame-{k:05d}.png"), 0) for k in range(5)]
    src = FlakySource(frames, lose_after=2, refuse=2)
    events = run(Watcher(src, stream["cal"], hysteresis=H, backoff=(0.01, 0.02), latest=False))
    back = [e for e in events if e["type"] == "reconnected"]
    assert len(back) == 1 and back[0]["reopened"] and back[0]["attempts"] == 3
    assert events[-1]["stats"]["frames_processed"] == 5 and events[-1]["stats"]["reconnects"] == 1
    # given up: two failed opens in a row end the watch, exit code 3
    src = FlakySource(frames, lose_after=2, refuse=10)
    watcher = Watcher(src, stream["cal"], hysteresis=H, backoff=(0.01, 0.02), max_reopen=2, latest=False)
    events = run(watcher)
    assert events[-1]["reason"] == "source-lost" and watcher.exit_code == EXIT_CODES["source-lost"] == 3
    assert "cannot open" in events[-1]["error"]


def test_frames_of_another_size_end_the_watch_with_an_error(stream):
    watcher = Watcher(IterableSource([np.zeros((100, 120), np.uint8)] * 3), stream["cal"])
    events = run(watcher)
    assert events[-1]["reason"] == "error" and watcher.exit_code == 1
    assert "120x100" in events[-1]["error"]
    with pytest.raises(InputError, match="run already"):
        next(watcher.events())


def test_undecodable_python_frames_are_skipped_and_counted(stream):
    img = cv2.imread(str(stream["folder"] / "frame-00000.png"), 0)
    events = run(Watcher(IterableSource([img, None, img, None, img], live=False), stream["cal"]))
    s = events[-1]["stats"]
    assert s["frames_corrupt"] == 2 and s["frames_processed"] == 3 and s["frames_missing"] == 0


def test_the_reader_hands_over_the_latest_frame_and_counts_drops():
    frames = [np.full((8, 8), i, np.uint8) for i in range(10)]
    taken = threading.Event()

    def camera():
        yield frames[0]
        taken.wait(30)  # the rest arrive while the pipeline is busy with frame 0
        yield from frames[1:]

    reader = FrameReader(IterableSource(camera(), live=False), latest=True)
    reader.start()
    first = reader.get(30)
    assert isinstance(first, Frame) and first.number == 0
    taken.set()
    for _ in range(3000):  # until the reader has read everything
        if reader.stats.read == 10:
            break
        threading.Event().wait(0.01)
    latest = reader.get(30)
    assert isinstance(latest, Frame) and latest.number == 9 and int(latest.image[0, 0]) == 9
    assert reader.stats.dropped == 8
    assert isinstance(reader.get(30), Notice)
    reader.stop()


def test_every_frame_mode_drops_nothing():
    frames = [np.full((8, 8), i, np.uint8) for i in range(10)]
    reader = FrameReader(IterableSource(frames, live=False), latest=False)
    reader.start()
    got = []
    while True:
        item = reader.get(1.0)
        if isinstance(item, Notice):
            break
        if item is not None:
            got.append(item.number)
    assert got == list(range(10)) and reader.stats.dropped == 0


# -- hysteresis and ids, on their own ------------------------------------------------------------------
def test_cell_hysteresis_in_frames_and_seconds():
    cells = CellHysteresis((1, 2), Hysteresis(frames=3))
    on = np.array([[True, False]])
    assert not cells.update(on, 0).any() and not cells.update(on, 100).any()
    assert cells.update(on, 200).tolist() == [[True, False]] and cells.stable.tolist() == [[True, False]]
    # one frame back to free, then occupied again: the run starts over, nothing flips
    off = np.zeros((1, 2), bool)
    for t, frame in enumerate([off, on, off, off]):
        assert not cells.update(frame, 300 + 100 * t).any()
    assert cells.update(off, 700).tolist() == [[True, False]]
    timed = CellHysteresis((1, 2), Hysteresis(frames=None, seconds=0.25))
    assert not timed.update(on, 0).any() and not timed.update(on, 200).any()
    assert timed.update(on, 250).any()
    both = CellHysteresis((1, 2), Hysteresis.parse("3,0.5s"))
    assert not any(both.update(on, t).any() for t in (0, 100, 200, 300))  # 3 frames, not yet 0.5 s
    assert both.update(on, 500).any()


@pytest.mark.parametrize("text", ["", "x", "0", "-1s", "2,xs"])
def test_bad_hysteresis_is_refused(text):
    with pytest.raises(InputError, match="hysteresis"):
        Hysteresis.parse(text)


def test_tracker_keeps_ids_through_moves_and_splits():
    from sbplan.detection.obstacles import Obstacle

    def ob(cells, centre):
        pts = np.array([[centre[0] - 1, centre[1] - 1], [centre[0] + 1, centre[1] - 1], [centre[0] + 1, centre[1] + 1]])
        return Obstacle(0, cells, pts, np.vstack([pts, pts[:1]]))

    t = ObstacleTracker(reach_px=10)
    out, ch = t.update([ob([(0, 0), (0, 1)], (5, 5)), ob([(3, 3)], (50, 50))])
    assert [o.id for o in out] == [1, 2] and [c.kind for c in ch] == ["appeared", "appeared"]
    # 1 slides and grows; 2 jumps a few pixels to a cell it did not cover (within reach)
    out, ch = t.update([ob([(0, 1), (0, 2), (0, 3)], (8, 5)), ob([(4, 3)], (55, 50))])
    assert [o.id for o in out] == [1, 2] and [c.kind for c in ch] == ["moved", "moved"]
    # 1 splits: the part sharing more cells keeps the id; 2 leaves
    out, ch = t.update([ob([(0, 1)], (7, 5)), ob([(0, 3), (0, 2)], (10, 5))])
    assert sorted((o.id, len(o.cells)) for o in out) == [(1, 2), (3, 1)]
    assert [c.kind for c in ch] == ["left", "moved", "appeared"]



def test_unchanged_groups_keep_their_obstacles():
    from sbplan.detection.obstacles import Obstacle
    from sbplan.live.tracking import reusable_obstacles

    def ob(cells):
        pts = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
        return Obstacle(0, cells, pts, np.vstack([pts, pts[:1]]))

    occ = np.zeros((4, 6), bool)
    occ[0, 0:2] = occ[3, 5] = occ[2, 2] = True
    stays, grows, new = ob([(0, 0), (0, 1)]), ob([(3, 5)]), None
    occ[2, 5] = True  # (3, 5) grows to (2, 5)
    kept, todo = reusable_obstacles(occ, [stays, grows])
    assert kept == [stays]  # the same object, its outline untouched
    assert sorted(zip(*np.nonzero(todo))) == [(2, 2), (2, 5), (3, 5)]  # the new one and the grown one
    # a group two obstacles share, an obstacle the caller refuses, one without cells: outlined anew
    assert reusable_obstacles(occ, [ob([(0, 0)]), ob([(0, 1)])])[0] == []
    assert reusable_obstacles(occ, [stays], keep=lambda o: False)[0] == []
    assert reusable_obstacles(occ, [stays, ob([])])[0] == []
    # an obstacle that shrank (its cell left) is outlined anew
    occ[0, 1] = False
    assert reusable_obstacles(occ, [stays])[0] == []


def test_an_obstacle_that_stays_keeps_its_outline_while_others_change(stream):
    """Only the obstacles whose cells changed are outlined again on the frame of a flip."""
    w = Watcher(stream["folder"], stream["cal"], hysteresis=H)
    outlines: dict[int, dict[int, np.ndarray]] = {}  # frame -> obstacle id -> outline, after frames with events
    events = []
    for e in w.events():
        events.append(e)
        if e["frame"] is not None and w.state.frame == e["frame"]:
            outlines[e["frame"]] = {o.id: o.outline_px for o in w.state.obstacles}
    kinds = [(e["type"], e["obstacle"]["id"], e["frame"]) for e in events if e["type"].startswith("obstacle_")]
    first = [f for k, i, f in kinds if k == "obstacle_appeared"]
    assert len(first) == 2  # the one that stays, then the one that slides
    stays = next(i for k, i, f in kinds if k == "obstacle_appeared" and f == first[0])
    # another obstacle appeared: the one that stays kept its outline (the same array: not outlined
    # again on a frame where it may look different)
    assert outlines[first[1]][stays] is outlines[first[0]][stays]
    moves = [e for e in events if e["type"] == "obstacle_moved"]
    assert moves and any(e["cells_added"] for e in moves)
    for e in moves:
        # the obstacle whose cells changed got a new outline, the one the state now holds
        assert e["obstacle"]["outline_px"] != e["previous"]["outline_px"]
        assert np.allclose(outlines[e["frame"]][e["obstacle"]["id"]], e["obstacle"]["outline_px"], atol=1e-3)
    # when the slider leaves, the one that stays is not outlined again (the camera stands still by then)
    left = next(f for k, i, f in kinds if k == "obstacle_left")
    assert outlines[left][stays] is outlines[moves[-1]["frame"]][stays]


# -- events out -------------------------------------------------------------------------------------
def test_every_event_follows_the_schema(stream, avi_events, folder_events, paused_events):
    import jsonschema
    validator = jsonschema.Draft202012Validator(events_schema())
    validator.check_schema(events_schema())
    kinds = set()
    # (the fixtures' events hold every kind named below, so the test stands alone when the suite is
    # split over processes; the other tests' watches add theirs when they ran in this one)
    for e in EVENTS_SEEN + avi_events + folder_events + paused_events:
        json.dumps(e)  # plain JSON
        errors = sorted(validator.iter_errors(e), key=str)
        assert not errors, f"{e['type']}: {errors[0].message}"
        kinds.add(e["type"])
    assert {"started", "obstacle_appeared", "obstacle_moved", "obstacle_left", "camera_moved", "stalled",
            "reconnected", "route", "ended"} <= kinds
    bad = dict(avi_events[-1], reason="bored")
    assert list(validator.iter_errors(bad))


def test_watch_command_writes_events_and_exits_as_documented(stream, tmp_path):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(Path(__file__).resolve().parents[1]),
                                                       os.environ.get("PYTHONPATH", "")]))
    out = tmp_path / "events.jsonl"
    cmd = [sys.executable, "-m", "sbplan", "watch", str(stream["avi"]), "-c", str(stream["cal_path"]),
           "--hysteresis", str(H), "--events", str(out), "--max-frames", "12"]
    p = subprocess.run(cmd, capture_output=True, text=True, env=env)
    assert p.returncode == 0, p.stderr
    lines = [json.loads(line) for line in out.read_text().splitlines()]
    assert lines[0]["type"] == "started" and lines[-1]["reason"] == "limit"
    assert lines[-1]["stats"]["frames_processed"] == 12
    assert "limit: 12 frames processed" in p.stderr
    p = subprocess.run([sys.executable, "-m", "sbplan", "watch", str(tmp_path / "nothing.avi"), "-c",
                        str(stream["cal_path"])], capture_output=True, text=True, env=env)
    assert p.returncode == 2 and p.stderr.count("\n") == 1 and "no such video file" in p.stderr
    # Ctrl-C: stops, flushes the last event, exit code 130
    proc = subprocess.Popen([sys.executable, "-m", "sbplan", "watch", str(stream["folder"]), "-c",
                             str(stream["cal_path"]), "--realtime", "0.2"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)
    first = json.loads(proc.stdout.readline())
    assert first["type"] == "started"
    proc.send_signal(signal.SIGINT)
    rest, err = proc.communicate(timeout=60)
    last = json.loads(rest.splitlines()[-1])
    assert proc.returncode == 130 and last["type"] == "ended" and last["reason"] == "interrupted", err


def test_a_stream_url_is_read_through_ffmpeg_and_a_dead_one_is_given_up(stream):
    """An HTTP URL on this machine (loopback only): the AVI served by a local server."""
    import functools
    import http.server
    import socket

    handler = functools.partial(http.server.SimpleHTTPRequestHandler, directory=str(stream["avi"].parent))
    handler.log_message = lambda *a: None
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        url = f"http://127.0.0.1:{server.server_address[1]}/{stream['avi'].name}"
        watcher = Watcher(url, stream["cal"], hysteresis=H, latest=False, max_frames=8, stall_timeout=5.0)
        events = run(watcher)
    finally:
        server.shutdown()
        server.server_close()
    assert events[0]["source"]["kind"] == "url" and events[0]["source"]["live"]
    assert events[-1]["reason"] == "limit" and events[-1]["stats"]["frames_processed"] == 8
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        dead = f"http://127.0.0.1:{s.getsockname()[1]}/none.avi"
    watcher = Watcher(dead, stream["cal"], backoff=(0.01, 0.02), max_reopen=2, stall_timeout=1.0)
    events = run(watcher)
    assert events[-1]["reason"] == "source-lost" and watcher.exit_code == 3
