"""The detection cache holds data only: a planted pickle or a corrupt entry is recomputed,
never executed; stale temporary files are cleaned."""

from __future__ import annotations

import hashlib
import io
import logging
import os
import pickle
import time

import numpy as np
import pytest

from tests.measure import synth_measure as sm
from vision_cal.dataset.session import load_session
from vision_cal.measure import detect
from vision_cal.actions.measure_folder import measure_folder
from vision_cal.measure.cache import (DetectionCache, cache_key, decode_detections,
                                     encode_detections, session_fingerprint)

N = 5
IDS = [f"c{i}" for i in range(N)]


class Planted:
    """Unpickling this runs code: it creates the file ``path``."""

    def __init__(self, path):
        self.path = str(path)

    def __reduce__(self):
        return (exec, (f"open({self.path!r}, 'w').write('pwned')",))


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    src = tmp_path_factory.mktemp("cache") / "in"
    src.mkdir()
    sheet = sm.small_sheet()
    targets = sm.free_targets(sheet, N, rng=21, box=(85.0, 62.0))
    q = sm.plan_for(targets)
    K, T = sm.view(tilt_deg=10.0, azimuth_deg=60.0)
    sm.write_png(src / "a.png", sm.photo(sheet, sm.texture(sheet, targets, rng=1), K=K, T=T))
    sm.write_png(src / "b.png", sm.photo(sheet, sm.texture(sheet, targets[:3], rng=1),
                                         K=K, T=T, rng=7))
    sm.write_session(src, sm.session_json(sheet, marks=list(zip(IDS, q)),
                                          images=[("a.png", IDS), ("b.png", IDS[:3])],
                                          robot=sm.NOMINAL))
    return src


def _count(monkeypatch):
    calls = []
    real = detect.detect_image

    def counting(path, session, **kw):
        calls.append(kw.get("name"))
        return real(path, session, **kw)

    monkeypatch.setattr(detect, "detect_image", counting)
    return calls


def _entries(cache):
    return sorted(cache.rglob("*.npz"))


def test_entries_are_data_only_and_round_trip(tmp_path, folder, monkeypatch):
    out = tmp_path / "out"
    m1 = measure_folder(load_session(folder), out_dir=out, jobs=1)
    ents = _entries(out / ".cache")
    assert len(ents) == 2
    for p in ents:
        with np.load(p, allow_pickle=False) as z:  # refuses any object array
            assert all(z[k].dtype != object for k in z.files)
    calls = _count(monkeypatch)
    m2 = measure_folder(load_session(folder), out_dir=out, jobs=1)
    assert calls == [] and all(im.from_cache for im in m2.images)
    for a, b in zip(m1.images, m2.images):
        np.testing.assert_array_equal(a.dots_xy_mm, b.dots_xy_mm)
        np.testing.assert_array_equal(a.markers_px, b.markers_px)
    assert set(m1.marks) == set(m2.marks) == set(IDS)


@pytest.mark.parametrize("plant", ["pickle", "pickle_as_npy", "corrupt", "other_key",
                                   "zip_bomb"])
def test_planted_or_corrupt_entry_is_recomputed_not_run(tmp_path, folder, monkeypatch, plant,
                                                         caplog):
    out = tmp_path / "out"
    measure_folder(load_session(folder), out_dir=out, jobs=1)
    cache = DetectionCache(out / ".cache")
    fp = session_fingerprint(load_session(folder))
    a_entry, b_entry = (cache._path(cache_key(hashlib.sha256((folder / f).read_bytes())
                                              .hexdigest(), fp)) for f in ("a.png", "b.png"))
    assert a_entry.exists() and b_entry.exists()
    marker = tmp_path / "pwned"
    if plant == "pickle":
        a_entry.write_bytes(pickle.dumps(Planted(marker)))
        # the old format's file name, next to it: removed, never read
        a_entry.with_suffix(".pkl").write_bytes(pickle.dumps(Planted(marker)))
    elif plant == "pickle_as_npy":
        buf = io.BytesIO()
        np.save(buf, np.array([Planted(marker)], dtype=object), allow_pickle=True)
        a_entry.write_bytes(buf.getvalue())
    elif plant == "corrupt":
        a_entry.write_bytes(a_entry.read_bytes()[:200])
    elif plant == "other_key":
        a_entry.write_bytes(b_entry.read_bytes())  # a valid entry, of another photo
    elif plant == "zip_bomb":
        buf = io.BytesIO()
        np.savez_compressed(buf, meta=np.array("{}"), big=np.zeros(300 * 2**20, np.uint8))
        a_entry.write_bytes(buf.getvalue())
    calls = _count(monkeypatch)
    with caplog.at_level(logging.INFO, logger="vision_cal.measure.cache"):
        m = measure_folder(load_session(folder), out_dir=out, jobs=1)
    assert not marker.exists(), "a planted cache entry ran code"
    if plant == "zip_bomb":  # refused from the zip directory, not inflated
        assert any("ignored: too large" in r.getMessage() for r in caplog.records)
    assert calls == ["a.png"]  # recomputed; b's good entry still used
    assert [im.from_cache for im in m.images] == [False, True]
    assert set(m.marks) == set(IDS)
    assert not list((out / ".cache").rglob("*.pkl"))
    # the recomputed entry replaced the bad one
    calls.clear()
    measure_folder(load_session(folder), out_dir=out, jobs=1)
    assert calls == []


def test_stale_temporary_files_are_cleaned(tmp_path):
    d = tmp_path / "cache" / "ab"
    d.mkdir(parents=True)
    old = d / ".abcd.npz.x1.tmp"
    new = d / ".abcd.npz.x2.tmp"
    old.write_bytes(b"half")
    new.write_bytes(b"being written")
    t = time.time() - 2 * 3600
    os.utime(old, (t, t))
    DetectionCache(tmp_path / "cache")
    assert not old.exists() and new.exists()


def test_decoder_checks_its_key():
    from vision_cal.measure.types import ImageDetections

    det = ImageDetections("a.png", "skipped", "blank image: no contrast", (10, 20))
    data = encode_detections(det, "k1")
    got = decode_detections(data, "k1")
    assert (got.file, got.status, got.reason, got.size_px) == (det.file, det.status,
                                                               det.reason, det.size_px)
    assert got.candidates is None and got.edges_px is None and len(got.marker_ids) == 0
    with pytest.raises(Exception):
        decode_detections(data, "k2")
