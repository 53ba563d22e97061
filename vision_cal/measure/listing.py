"""The photos to measure, before anything is decoded: listed in session.json or found in the
folder (by capture time), each read once in this process and checked (regular file inside
the folder, header within the limits); a repeated or refused photo is skipped with its
one-line reason."""

from __future__ import annotations

import hashlib
import logging
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

from vision_cal.dataset import photos
from vision_cal.dataset.session import Session
from vision_cal.errors import VisionCalError
from vision_cal.measure.types import ImageDetections

log = logging.getLogger(__name__)


def skipped(file, why, size=None) -> ImageDetections:
    """A photo left out before its markers are measured, with the reason (``size``: its
    (width, height) px when known)."""
    return ImageDetections(file, "skipped", why, size)


def refusal(file: str, e: "photos.PhotoRefused") -> str:
    """The reason a photo is refused; a camera format not read (HEIC, raw) says so and how
    to fix it, listed in session.json or found in the folder alike."""
    if e.reason.startswith("unreadable: not an image") and file.lower().endswith(
            photos.UNREAD_SUFFIXES):
        return (f"a {file.rsplit('.', 1)[-1].upper()} file, a format not read: convert it to "
                "JPEG or PNG")
    return e.reason


@dataclass
class Photo:
    """One photo before stage 1: its name, and what the parent learnt from its header."""

    file: str
    listed_marks: tuple | None
    det: ImageDetections | None = None
    sha256: str | None = None
    captured: object = None
    pixels: int = 0
    key: str | None = None
    cached: bool = False
    #: the file's identity when it was hashed (:func:`photos.read_photo_identity`): a
    #: worker reading the same identity reads the same bytes and need not hash them again
    identity: tuple | None = None


def _check_photo(ph: Photo, root: Path, session: Session) -> None:
    """Read the photo once in the parent, before any worker sees it: regular file inside
    the folder, header within the limits (no pixel decoded). Fills ``sha256``, ``captured``
    ``identity`` or a skip (``det``)."""
    cam = session.camera
    try:
        data, identity = photos.read_photo_identity(root, ph.file)
        if not data:
            raise photos.PhotoRefused("unreadable: empty file")
        header = photos.read_header(data)
        photos.check_header(header, None if cam is None else cam.size_px)
    except photos.PhotoRefused as e:
        ph.det = skipped(ph.file, refusal(ph.file, e))
        return
    ph.sha256 = hashlib.sha256(data).hexdigest()
    ph.identity = identity
    ph.captured = header.captured
    ph.pixels = header.stored_px[0] * header.stored_px[1]


def _capture_order(items: list[Photo], warnings: list) -> list[Photo]:
    """Photos found in the folder: by EXIF capture time when every readable photo has one,
    else by natural file name (already the order of ``items``)."""
    readable = [p for p in items if p.det is None]
    timed = [p for p in readable if p.captured is not None]
    if readable and len(timed) == len(readable):
        rank = {id(p): i for i, p in enumerate(items)}
        return sorted(items, key=lambda p: (p.captured is None, p.captured or datetime.min,
                                            rank[id(p)]))
    if timed:
        warnings.append(f"{len(readable) - len(timed)} of {len(readable)} photos have no EXIF "
                        "capture time: all are ordered by file name")
    return items


def photos_to_measure(session: Session) -> tuple[list[Photo], list[str], list[str]]:
    """The photos to measure, in order (listed in session.json, or found in the folder by
    capture time), each read once and checked here before any worker sees it; a repeated
    file is skipped. Returns (photos, warnings, notes: what the console should see when
    session.json lists no images)."""
    root = Path(session.root)
    warnings: list[str] = []
    notes: list[str] = []
    try:
        present = photos.list_photos(root)
    except OSError as e:
        if not session.images_listed:
            raise VisionCalError(f"cannot list the photos: {e.strerror or e}",
                                 file=str(root)) from e
        present = []
    if session.images_listed:
        items = [Photo(im.file, im.marks) for im in session.images]
        listed = {im.file for im in session.images}
        extra = [f for f in present if f not in listed]
        if extra:
            msg = (f"{len(extra)} image file(s) in {root} not listed in session.json, left "
                   "alone: " + ", ".join(extra[:10]) + (" ..." if len(extra) > 10 else ""))
            log.warning(msg)
            warnings.append(msg)
    else:
        unread = photos.list_unread(root)
        conv = (f"; {len(unread)} file(s) of a format not read ({unread[0]}"
                f"{', ...' if len(unread) > 1 else ''}): convert them to JPEG or PNG"
                if unread else "")
        if not present:
            raise VisionCalError("no photos: session.json has no images list and the folder "
                                 f"has no {'/'.join(s[1:] for s in photos.PHOTO_SUFFIXES)} "
                                 f"file{conv}", file=str(session.path), field="images")
        if unread:
            notes.append(conv[2:])
        items = [Photo(f, None) for f in present]

    # checked in this process before anything is decoded or dispatched
    for ph in items:
        _check_photo(ph, root, session)
    if not session.images_listed:
        items = _capture_order(items, notes)
        warnings.extend(notes)
    first_of: dict[str, str] = {}
    for ph in items:
        if ph.det is None and ph.sha256 in first_of:
            ph.det = skipped(ph.file, f"repeated photo: the same file as {first_of[ph.sha256]}")
        elif ph.det is None:
            first_of[ph.sha256] = ph.file
    return items, warnings, notes
