"""A photo is hashed once (issue 33): its worker reads it back and hashes it again only when
the file's identity (inode, size, modification and change times) is not the one it had
when the listing hashed it; a file changed in between is still caught."""

from __future__ import annotations

import hashlib
import os

import numpy as np

from tests.measure import synth_measure as sm
from vision_cal.dataset.session import load_session
from vision_cal.measure import detect
from vision_cal.measure.listing import _check_photo, Photo


def _one_photo(tmp_path):
    sheet = sm.small_sheet()
    targets = sm.free_targets(sheet, 3, rng=5, box=(85.0, 62.0))
    ids = [f"c{i}" for i in range(len(targets))]
    src = tmp_path / "in"
    src.mkdir()
    K, T = sm.view(tilt_deg=8.0, azimuth_deg=30.0)
    sm.write_png(src / "p0.png", sm.photo(sheet, sm.texture(sheet, targets, rng=1), K=K, T=T,
                                          rng=3))
    sm.write_session(src, sm.session_json(sheet, marks=list(zip(ids, sm.plan_for(targets))),
                                          images=[("p0.png", ids)], robot=sm.NOMINAL))
    session = load_session(src)
    ph = Photo("p0.png", tuple(ids))
    _check_photo(ph, src, session)
    assert ph.det is None and ph.sha256 and ph.identity
    return src, session, ph


def _detect(src, session, ph):
    return detect.detect_image(src / ph.file, session, root=src, name=ph.file,
                               sha256=ph.sha256, identity=ph.identity)


def test_an_unchanged_photo_is_not_hashed_again(tmp_path, monkeypatch):
    src, session, ph = _one_photo(tmp_path)
    calls = []
    real = hashlib.sha256
    monkeypatch.setattr(detect.hashlib, "sha256", lambda b: calls.append(1) or real(b))
    d = _detect(src, session, ph)
    assert d.status == "ok" and not calls


def test_a_photo_changed_after_the_listing_is_skipped(tmp_path):
    src, session, ph = _one_photo(tmp_path)
    path = src / ph.file
    data = bytearray(path.read_bytes())
    st = path.stat()
    data[-20] ^= 0xFF                              # same size, other bytes
    path.write_bytes(bytes(data))
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))   # even with the old mtime
    d = _detect(src, session, ph)
    assert d.status == "skipped" and d.reason.startswith("changed while being measured")
    # touched but the same bytes: hashed again, and measured
    path.write_bytes(bytes(data[:-20]) + bytes([data[-20] ^ 0xFF]) + bytes(data[-19:]))
    d = _detect(src, session, ph)
    assert d.status == "ok"
    assert np.asarray(d.marker_ids).size
