"""The arm camera's photos go through the measurement every photo goes through (issue 39):
the session read by ``dataset/session.load_arm_session``, the photos listed and checked by
``measure/listing``, their markers found by ``measure/detect`` (cached by content, the
markers only) and a photo that cannot be used skipped with the measurement's own reason.
No render here: a photo that is not one, a missing one and a repeated one."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from vision_cal.dataset.session import MAX_POSES, Session, load_arm_session, load_session
from vision_cal.errors import VisionCalError
from vision_cal.measure.cache import session_fingerprint
from vision_cal.measure.listing import photos_to_measure
from vision_cal.actions.arm_camera import measure_arm_photos
from vision_cal.world.arm_camera import field_sheet

ROBOT = {"L1_mm": 350.0, "L2_mm": 260.0, "joint_zero_deg": [0.0, 0.0],
         "base_mm": [-410.0, -240.0], "home_deg": [0.0, 0.0]}


def _session(folder, poses, **extra):
    """session.json of ``poses`` ((image, q, j4) each) in ``folder``."""
    folder.mkdir(exist_ok=True)
    s = {"format": "vision-cal/1", "sheet": field_sheet().to_json(), "robot": ROBOT,
         "poses": [{"image": f, "joints_deg": q, "j4_deg": j4} for f, q, j4 in poses],
         **extra}
    (folder / "session.json").write_text(json.dumps(s))
    return folder


def test_the_poses_are_the_sessions_photos_with_their_approach(tmp_path):
    """``poses`` read into the session: its photos in order (what the listing reads), each
    command and the format's approach rule over them from home."""
    s = load_arm_session(_session(tmp_path / "a", [("p0.png", [10.0, 20.0], 0.0),
                                                    ("p1.png", [5.0, 20.0], 10.0),
                                                    ("./p2.png", [5.0, 30.0], 20.0)]))
    assert isinstance(s, Session) and s.marks == () and s.camera_mount == "flange"
    assert [im.file for im in s.images] == ["p0.png", "p1.png", "p2.png"]
    assert [p.approach for p in s.poses] == [(1.0, 1.0), (-1.0, 1.0), (-1.0, 1.0)]
    assert s.poses[2].joints_deg == (5.0, 30.0) and s.poses[2].j4_deg == 20.0
    # a pen session's reader refuses it (no marks), naming the field
    with pytest.raises(VisionCalError, match="marks"):
        load_session(tmp_path / "a")


@pytest.mark.parametrize("poses,extra,field", [
    ([("p.png", [0.0, 20.0], 0.0)] * (MAX_POSES + 1), {}, "poses"),
    ([("p.png", [0.0, 20.0], 0.0)], {"camera_mount": "wrist"}, "camera_mount"),
    ([("p.png", [0.0, 20.0], 5.0)], {"camera_mount": "link2"}, "poses[0].j4_deg"),
    ([("../p.png", [0.0, 20.0], 0.0)], {}, "poses[0].image"),
])
def test_a_bad_pose_field_is_named(tmp_path, poses, extra, field):
    with pytest.raises(VisionCalError) as e:
        load_arm_session(_session(tmp_path / "a", poses, **extra))
    assert e.value.field == field, str(e.value)


def test_an_unusable_photo_is_skipped_with_the_measurements_reason(tmp_path):
    """Not an image, missing, and the same file as an earlier pose: skipped with the
    reasons the listing and stage 1 give any photo; the cache is written beside them."""
    folder = _session(tmp_path / "a", [("a.png", [0.0, 20.0], 0.0), ("b.png", [5.0, 20.0], 0.0),
                                       ("c.png", [9.0, 20.0], 0.0), ("d.png", [9.0, 30.0], 0.0)])
    (folder / "a.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 64)
    (folder / "c.png").write_bytes(cv2.imencode(".png", np.full((48, 64), 200, np.uint8))[1])
    (folder / "d.png").write_bytes((folder / "c.png").read_bytes())
    session = load_arm_session(folder)
    views, images = measure_arm_photos(session, cache_dir=tmp_path / "cache")
    items, _, _ = photos_to_measure(session)
    assert views == []
    assert [im["file"] for im in images] == ["a.png", "b.png", "c.png", "d.png"]
    assert all(im["status"] == "skipped" and im["reason"] for im in images)
    # the listing's reasons, as for a pen session's photos (b.png missing, d.png repeated)
    for im, ph in zip(images, items):
        if ph.det is not None:
            assert im["reason"] == ph.det.reason
    assert images[2]["reason"] == "blank image: no contrast"            # stage 1's
    assert images[3]["reason"] == "repeated photo: the same file as c.png"


def test_the_markers_only_detections_are_cached_apart(tmp_path):
    """Stage 1 on the markers only (the arm's photos) is cached under another key than a
    pen session's of the same sheet: neither reads the other's detections."""
    s = load_arm_session(_session(tmp_path / "a", [("p.png", [0.0, 20.0], 0.0)]))
    assert session_fingerprint(s, dots=False) != session_fingerprint(s)
    assert session_fingerprint(s) == session_fingerprint(s, dots=True)
