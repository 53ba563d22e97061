"""Photo files of a dataset folder: names, reading, headers, decoding (the one owner).

Every photo of a dataset goes through these functions, whether ``session.json`` lists it
or it was found in the folder:

- :func:`normalise_name`: ``images[].file`` as written -> the relative POSIX path that
  names the photo everywhere (results, cache, report): ``./a.png`` is ``a.png``,
  ``photos/x.png`` stays ``photos/x.png``; absolute paths, ``..``, NUL bytes, empty parts
  and backslashes are refused.
- :func:`list_photos`: every image file directly in the folder (``images`` absent), in
  natural name order (``img_2`` before ``img_10``).
- :func:`read_photo`: the bytes of one photo, or :class:`PhotoRefused` with a one-line
  reason. Only a regular file inside the dataset folder is read: a symlink that resolves
  outside the folder is refused, a FIFO or device is refused without blocking (opened with
  ``O_NONBLOCK`` and checked with ``fstat`` on the open descriptor, so nothing can be
  swapped in between), a file above :data:`MAX_FILE_BYTES` is refused unread.
- :func:`read_header`: size, depth, EXIF orientation and capture time from the header,
  with Pillow, lazily (nothing is decoded).
- :func:`check_header`: refuses a decompression bomb before anything is decoded: more than
  :data:`MAX_PIXELS` (100 MP), or, when the session declares ``camera.size_px``, a size that
  is neither the camera's nor its rotation.
- :func:`decode_photo`: the pixels, in the frame :func:`check_header` chose.

EXIF orientation (OpenCV 5's ``imread``/``imdecode`` rotate by it unless told
``IMREAD_IGNORE_ORIENTATION``): photos are measured in the **sensor's stored pixel grid**,
the frame of ``camera.K``. A phone held upright stores the same sensor pixels as one held
flat and only tags the file; measuring every photo in the stored frame keeps one lens for
one camera whatever the tag says, and is the same whether or not ``camera.size_px`` is
declared. The one exception: a declared camera whose ``size_px`` matches the *displayed*
(rotated) size but not the stored one was described in the displayed frame, so that photo
is decoded rotated.
"""

from __future__ import annotations

import io
import os
import re
import stat
import struct
import warnings
import zlib
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path, PurePosixPath

import numpy as np
from PIL import Image, UnidentifiedImageError

PHOTO_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".webp")
#: camera formats neither Pillow nor OpenCV reads here (HEIC from phones, raw files):
#: named in a warning, so that they do not vanish silently
UNREAD_SUFFIXES = (".heic", ".heif", ".avif", ".dng", ".cr2", ".cr3", ".nef", ".arw", ".raf",
                   ".orf", ".rw2")
#: largest photo measured (pixels): a 100 MP frame is ~300 MB decoded (8-bit RGB), above
#: any phone or DSLR the sheet is photographed with; a larger header is a bomb or a scan
MAX_PIXELS = 100_000_000
#: largest file read (bytes): 100 MP of 16-bit RGB stored raw
MAX_FILE_BYTES = 600 * 1024 * 1024

#: EXIF Orientation values that swap width and height (90 or 270 degree turns)
_TRANSPOSING = (5, 6, 7, 8)


class PhotoRefused(Exception):
    """A photo that is not read or not decoded; ``reason`` is the one-line why."""

    def __init__(self, reason: str):
        super().__init__(reason)
        self.reason = reason


# --------------------------------------------------------------------------- names

def normalise_name(name: str) -> str:
    """The relative POSIX path naming a photo in its dataset folder; ValueError with a
    reason for a name that cannot be one."""
    if not isinstance(name, str) or not name:
        raise ValueError(f"expected a file name, got {name!r}")
    if "\x00" in name:
        raise ValueError(f"expected a file name, got one with a NUL byte: {name!r}")
    if "\\" in name:
        raise ValueError(f"expected '/' between folders, got a backslash: {name!r}")
    p = PurePosixPath(name)
    if p.is_absolute() or ".." in p.parts:
        raise ValueError(f"expected a file name inside the dataset folder, got {name!r}")
    parts = [s for s in p.parts if s != "."]
    if not parts:
        raise ValueError(f"expected a file name, got {name!r}")
    return "/".join(parts)


def natural_key(name: str):
    """Sort key: digit runs compare as numbers (``img_2`` < ``img_10``)."""
    return [(0, int(t), "") if t.isdigit() else (1, 0, t.lower())
            for t in re.split(r"(\d+)", name) if t] + [(2, 0, name)]


def is_photo_name(name: str) -> bool:
    return not name.startswith(".") and name.lower().endswith(PHOTO_SUFFIXES)


#: pictures ``vision-cal design`` writes beside session.json: never photos of the sheet
DESIGN_PICTURES = ("preview.png",)


def list_photos(root) -> list[str]:
    """Image files directly in ``root`` (not hidden, not :data:`DESIGN_PICTURES`), natural
    name order. Anything that is not a regular file after following links is left for
    :func:`read_photo` to refuse with its reason, so it shows in the report instead of
    vanishing."""
    root = Path(root)
    names = [e.name for e in os.scandir(root) if is_photo_name(e.name)
             and e.name not in DESIGN_PICTURES]
    return sorted(names, key=natural_key)


def list_unread(root) -> list[str]:
    """Files directly in ``root`` of a camera format that is not read (HEIC, raw)."""
    return sorted((e.name for e in os.scandir(root) if not e.name.startswith(".")
                   and e.name.lower().endswith(UNREAD_SUFFIXES)), key=natural_key)


# --------------------------------------------------------------------------- reading

def _inside(path: Path, root: Path) -> bool:
    try:
        path.relative_to(root)
        return True
    except ValueError:
        return False


def read_photo(root, name: str) -> bytes:
    """The bytes of photo ``name`` (a :func:`normalise_name` path) of folder ``root``."""
    return read_photo_identity(root, name)[0]


def read_photo_identity(root, name: str) -> tuple[bytes, tuple]:
    """(bytes, identity) of photo ``name`` of folder ``root`` (:func:`read_photo`): the
    identity is the file's device, inode, size, modification and change times (ns) as
    they were when the read ended. Any write to the file changes its change time (which no
    user can set back), so an equal identity read later is the same content; a different
    one may not be (issue 33: a photo hashed once, read again by its worker)."""
    root_real = Path(os.path.realpath(root))
    path = Path(root) / name
    real = Path(os.path.realpath(path))
    if not _inside(real, root_real):
        raise PhotoRefused("refused: it resolves outside the dataset folder (a symlink?)")
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise PhotoRefused("missing: file not found") from None
    except OSError as e:
        raise PhotoRefused(f"unreadable: {e.strerror or e}") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            kind = ("a folder" if stat.S_ISDIR(st.st_mode) else
                    "a FIFO" if stat.S_ISFIFO(st.st_mode) else
                    "a socket" if stat.S_ISSOCK(st.st_mode) else "a device")
            raise PhotoRefused(f"refused: not a regular file ({kind})")
        if st.st_size > MAX_FILE_BYTES:
            raise PhotoRefused(f"refused: {st.st_size / 2**20:.0f} MiB file, above the "
                               f"{MAX_FILE_BYTES / 2**20:.0f} MiB limit for a photo")
        chunks = []
        left = MAX_FILE_BYTES + 1
        while left > 0:
            b = os.read(fd, min(left, 1 << 22))
            if not b:
                break
            chunks.append(b)
            left -= len(b)
        data = b"".join(chunks)
        if len(data) > MAX_FILE_BYTES:
            raise PhotoRefused(f"refused: file grew above the {MAX_FILE_BYTES / 2**20:.0f} "
                               "MiB limit while being read")
        st = os.fstat(fd)
        return data, (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)
    except OSError as e:
        raise PhotoRefused(f"unreadable: {e.strerror or e}") from None
    finally:
        os.close(fd)


# --------------------------------------------------------------------------- header

@dataclass(frozen=True)
class PhotoHeader:
    """What the file's header says, nothing decoded. ``stored_px`` (w, h) as the pixels are
    stored; ``orientation`` the EXIF tag (1 upright); ``displayed_px`` after turning by it;
    ``bits`` per channel; ``captured`` EXIF DateTimeOriginal (+ sub-seconds) or None."""

    format: str
    stored_px: tuple[int, int]
    mode: str
    orientation: int = 1
    captured: datetime | None = None

    @property
    def displayed_px(self) -> tuple[int, int]:
        w, h = self.stored_px
        return (h, w) if self.orientation in _TRANSPOSING else (w, h)

    @property
    def bits(self) -> int:
        return 16 if self.mode in ("I;16", "I;16B", "I;16L", "I", "F", "RGB;16") else 8


def _capture_time(exif) -> datetime | None:
    try:
        sub = exif.get_ifd(0x8769)  # the Exif IFD
    except Exception:  # noqa: BLE001 - a broken EXIF block is no capture time
        return None
    raw = sub.get(0x9003) or exif.get(0x0132)  # DateTimeOriginal, else DateTime
    if not isinstance(raw, str):
        return None
    try:
        t = datetime.strptime(raw.strip("\x00 ").strip(), "%Y:%m:%d %H:%M:%S")
    except ValueError:
        return None
    frac = sub.get(0x9291)  # SubSecTimeOriginal
    if isinstance(frac, str) and frac.strip("\x00 ").isdigit():
        f = frac.strip("\x00 ")
        t = t.replace(microsecond=int(f[:6].ljust(6, "0")))
    return t


def read_header(data: bytes) -> PhotoHeader:
    """The photo's header (Pillow, lazily: ``Image.open`` reads the header, never the
    pixels). Pillow's own bomb guard (``Image.MAX_IMAGE_PIXELS``: a warning above 89 MP,
    an error above twice that) is handled here, explicitly: its warning is silenced and
    its error becomes a reason, because :func:`check_header` applies the limits."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            with Image.open(io.BytesIO(data)) as im:
                size = (int(im.size[0]), int(im.size[1]))
                fmt, mode = str(im.format), str(im.mode)
                try:
                    # EXIF from what the header gave: Pillow's getexif() on a PNG decodes
                    # the whole image to look for an eXIf chunk after the pixels
                    if fmt in ("TIFF", "MPO", "JPEG"):
                        exif = im.getexif()
                    else:
                        exif = Image.Exif()
                        if im.info.get("exif"):
                            exif.load(im.info["exif"])
                    orient = int(exif.get(0x0112, 1) or 1)
                    captured = _capture_time(exif)
                except Exception:  # noqa: BLE001 - unreadable EXIF: upright, no time
                    orient, captured = 1, None
    except Image.DecompressionBombError as e:
        m = re.search(r"\((\d+) pixels\)", str(e))
        n = f"{int(m.group(1)) / 1e6:.0f} MP" if m else "too many pixels"
        raise PhotoRefused(f"refused before decoding: the header claims {n}, above the "
                           f"{MAX_PIXELS / 1e6:.0f} MP limit (a decompression bomb?)") from None
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError, EOFError):
        raise PhotoRefused("unreadable: not an image (no header Pillow can identify)") from None
    if orient not in range(1, 9):
        orient = 1
    return PhotoHeader(fmt, size, mode, orient, captured)


def check_header(h: PhotoHeader, camera_size_px=None) -> bool:
    """Refuse (:class:`PhotoRefused`) what must not be decoded; return whether to decode
    it turned by its EXIF orientation (see the module doc: normally not).

    With ``camera.size_px`` declared only that size (stored, or displayed after an EXIF
    turn) is decoded; without, anything up to :data:`MAX_PIXELS`."""
    w, h_ = h.stored_px
    n = w * h_
    if w <= 0 or h_ <= 0:
        raise PhotoRefused(f"unreadable: the header says {w}x{h_} px")
    if camera_size_px is not None:
        cam = (int(camera_size_px[0]), int(camera_size_px[1]))
        if tuple(h.stored_px) == cam:
            return False
        if h.orientation in _TRANSPOSING and h.displayed_px == cam:
            return True
        raise PhotoRefused(f"wrong size: {w}x{h_} px ({n / 1e6:.1f} MP, not decoded), "
                           f"camera.size_px says {cam[0]}x{cam[1]}")
    if n > MAX_PIXELS:
        raise PhotoRefused(f"refused before decoding: {w}x{h_} px ({n / 1e6:.0f} MP) is above "
                           f"the {MAX_PIXELS / 1e6:.0f} MP limit (a decompression bomb?)")
    return False


def check_complete(data: bytes) -> None:
    """Refuse (:class:`PhotoRefused`) a PNG or JPEG that ends before its image does, judged
    by walking its structure from the start, not by its last bytes: bytes after the end
    (Samsung's trailer, a motion photo's video, an appended depth map) are left alone, as
    every decoder leaves them. PNG: each chunk's length and CRC up to ``IEND`` (a chunk
    failing its CRC is named here, before libpng prints its own line). JPEG: each segment
    up to the first scan, then the scans up to the end marker ``FFD9``. Other formats are
    left to the decoder."""
    if data[:8] == b"\x89PNG\r\n\x1a\n":
        pos = 8
        while True:
            if pos + 12 > len(data):
                raise PhotoRefused("truncated: the PNG ends before its IEND chunk")
            n, kind = struct.unpack(">I4s", data[pos:pos + 8])
            end = pos + 12 + n
            if end > len(data):
                raise PhotoRefused("truncated: the PNG ends inside its "
                                   f"{kind.decode('latin-1')!s} chunk")
            crc = struct.unpack(">I", data[end - 4:end])[0]
            if zlib.crc32(data[pos + 4:end - 4]) & 0xFFFFFFFF != crc:
                raise PhotoRefused(f"corrupt: the PNG's {kind.decode('latin-1')} chunk fails "
                                   "its CRC check (a damaged copy?)")
            if kind == b"IEND":
                return
            pos = end
    if data[:2] == b"\xff\xd8":
        truncated = PhotoRefused("truncated: the JPEG ends before its end marker")
        pos = 2
        while True:
            # a marker: FF (any fill FFs) then its code
            while pos < len(data) and data[pos] == 0xFF and pos + 1 < len(data) \
                    and data[pos + 1] == 0xFF:
                pos += 1
            if pos + 2 > len(data) or data[pos] != 0xFF:
                raise truncated if pos + 2 > len(data) else PhotoRefused(
                    "corrupt: the JPEG's segments do not follow each other")
            code = data[pos + 1]
            if code == 0xD9:  # EOI
                return
            if code == 0x01 or 0xD0 <= code <= 0xD7:  # no length
                pos += 2
                continue
            if pos + 4 > len(data):
                raise truncated
            n = struct.unpack(">H", data[pos + 2:pos + 4])[0]
            pos += 2 + n
            if pos > len(data):
                raise truncated
            if code == 0xDA:  # a scan: its entropy-coded data runs to the next marker
                while True:
                    pos = data.find(b"\xff", pos)
                    if pos < 0 or pos + 1 >= len(data):
                        raise truncated
                    nxt = data[pos + 1]
                    if nxt == 0x00 or 0xD0 <= nxt <= 0xD7:
                        pos += 2  # stuffed FF, or a restart marker inside the scan
                        continue
                    if nxt == 0xFF:
                        pos += 1  # fill byte before a marker
                        continue
                    break


def decode_photo(data: bytes, *, turned: bool = False):
    """BGR uint8 pixels (OpenCV), in the stored frame unless ``turned``; None if OpenCV
    cannot decode them."""
    # OpenCV takes 0.2 s to import: loaded here, when used
    import cv2

    flags = cv2.IMREAD_COLOR if turned else cv2.IMREAD_COLOR | cv2.IMREAD_IGNORE_ORIENTATION
    try:
        return cv2.imdecode(np.frombuffer(data, np.uint8), flags)
    except cv2.error:
        return None


def channel_sum(rgb: np.ndarray, dtype=np.float32) -> np.ndarray:
    """B+G+R of (H, W, 3) uint8 pixels in ``dtype`` (exact: at most 765): three plane
    additions, several times faster than numpy's sum over the last, 3-long axis."""
    out = rgb[..., 0].astype(dtype)
    out += rgb[..., 1]
    out += rgb[..., 2]
    return out


def decode_as_measured(data: bytes, size_px=None):
    """Pixels in the frame a photo was measured in (``size_px`` (w, h) of the measurement;
    the stored frame unless only the turned one has that size), for drawing overlays."""
    try:
        h = read_header(data)
        turned = (size_px is not None and tuple(h.stored_px) != tuple(size_px)
                  and h.displayed_px == tuple(size_px))
        if size_px is None and h.stored_px[0] * h.stored_px[1] > MAX_PIXELS:
            return None
    except PhotoRefused:
        return None
    return decode_photo(data, turned=turned)


def load_photo(root, name: str, camera_size_px=None):
    """Read, check and decode one photo: (BGR pixels, header, bytes); PhotoRefused else."""
    data = read_photo(root, name)
    header = read_header(data)
    turned = check_header(header, camera_size_px)
    return decode_photo(data, turned=turned), header, data
