"""The printable calibration sheet (``vision-cal sheet``): its layout
(:func:`vision_cal.sheet.make_layout`, or a marker field for an arm camera,
:func:`vision_cal.sheet.field.make_field_layout`) written as PDF, SVG, sheet.json (and PNG)
into a locked folder that holds no other sheet."""

from __future__ import annotations

from dataclasses import dataclass

from vision_cal.actions.console import say
from vision_cal.dataset.io import written_together
from vision_cal.dataset.out_folder import refuse_other_sheet, writing_into
from vision_cal.errors import VisionCalError
from vision_cal.sheet import SheetLayout, make_layout, write_sheet
from vision_cal.sheet.charuco import charuco_spec, make_charuco_layout, parse_squares
from vision_cal.sheet.field import make_field_layout

#: the markers' dictionary when none is given: a ruled sheet's, a marker field's
DEFAULT_DICT = "DICT_5X5_100"
FIELD_DICT = "DICT_5X5_1000"


@dataclass(frozen=True)
class SheetRequest:
    """What ``vision-cal sheet`` was asked (see its ``--help``)."""

    out: str
    size: str | None = None                        # ISO page (default A3)
    custom: tuple[float, float] | None = None      # page width, height (mm)
    landscape: bool | None = None
    dictionary: str | None = None                  # default DEFAULT_DICT (field: FIELD_DICT)
    marker_mm: float | None = None
    pitch_mm: float | None = None
    field: bool = False                            # a marker field for an arm camera
    png_dpi: float | None = None
    measured_bar_mm: tuple[float, float] | None = None
    charuco: str | None = None                     # COLSxROWS: an OpenCV ChArUco board
    square_mm: float | None = None                 # its squares (mm)
    legacy_pattern: bool = False                   # OpenCV's pattern before 4.6
    quiet: bool = False


@dataclass(frozen=True)
class SheetOutcome:
    """The layout written and its files (kind -> path)."""

    layout: SheetLayout
    paths: dict

    def lines(self) -> list[str]:
        """``vision-cal sheet``: the page, the markers, the files, and how to print."""
        layout = self.layout
        spec = getattr(layout, "spec", None)    # a ChArUco board (sheet/charuco.py)
        files = ", ".join(str(p) for p in self.paths.values())
        if spec is not None:
            return [f"sheet {layout.sheet_id}: ChArUco {spec.squares[0]}x{spec.squares[1]} "
                    f"squares of {spec.square_mm:g} mm, {len(layout.markers)} "
                    f"{layout.dictionary} markers of {spec.marker_mm:g} mm on {layout.page} "
                    f"{layout.orientation} -> " + files,
                    f"print at 100 % (actual size) and check that a square measures "
                    f"{spec.square_mm:g} mm; glue it flat on a rigid plate"]
        head = (f"sheet {layout.sheet_id}: {layout.page} {layout.orientation} "
                f"{layout.size_mm[0]:g} x {layout.size_mm[1]:g} mm, {len(layout.markers)} "
                f"{layout.dictionary} markers of {layout.marker_mm:g} mm -> " + files)
        if not layout.bars_mm:   # a marker field (sheet --field): no bars
            return [head, "print at 100 % (actual size) and tape it flat"]
        return [head, "print at 100 % (actual size); measure both 100 mm bars with a caliper "
                      "and give them to the calibration (--bars-mm X Y)"]

    def show(self, quiet: bool = False) -> int:
        if not quiet:
            say(self.lines())
        return 0


def sheet(req: SheetRequest) -> SheetOutcome:
    """Lay out the sheet of ``req`` and write it into ``req.out``."""
    if req.size is not None and req.custom is not None:
        raise VisionCalError("give either --size or --custom, not both", field="--custom")
    if req.charuco is not None:
        layout = _charuco_layout(req)
    elif req.square_mm is not None or req.legacy_pattern:
        raise VisionCalError("applies to --charuco only",
                             field="--square-mm" if req.square_mm is not None
                             else "--legacy-pattern")
    elif req.field:
        layout = make_field_layout(
            size=req.size or "A3", landscape=req.landscape, custom_mm=req.custom,
            dictionary=req.dictionary or FIELD_DICT, marker_mm=req.marker_mm,
            pitch_mm=req.pitch_mm)
    else:
        layout = make_layout(size=req.size or "A3", landscape=req.landscape,
                             custom_mm=req.custom, dictionary=req.dictionary or DEFAULT_DICT,
                             marker_mm=req.marker_mm, pitch_mm=req.pitch_mm,
                             measured_bar_mm=req.measured_bar_mm)
    # another sheet in the folder (the one the plans were designed on) is never replaced;
    # the earlier files of this one go to previous/sheet/ (a PNG this run does not write
    # among them); the folder is locked while written (issue 30)
    refuse_other_sheet(req.out, layout.sheet_id)
    with writing_into(req.out, command="sheet", quiet=req.quiet) as out, written_together():
        paths = write_sheet(layout, out, png_dpi=req.png_dpi)
    return SheetOutcome(layout, paths)


def _charuco_layout(req: SheetRequest):
    """The ChArUco board of ``req`` (its options checked: no ring sheet's option with it)."""
    for name, v in (("--field", req.field), ("--pitch-mm", req.pitch_mm),
                    ("--measured-bar-mm", req.measured_bar_mm)):
        if v:
            raise VisionCalError("does not apply to a ChArUco board (--charuco)", field=name)
    if req.dictionary is None:
        raise VisionCalError("a ChArUco board needs its markers' dictionary (OpenCV's "
                             "tutorial boards use DICT_6X6_250)", field="--dictionary")
    spec = charuco_spec(parse_squares(req.charuco), req.square_mm, req.marker_mm,
                        req.dictionary, req.legacy_pattern)
    return make_charuco_layout(spec, size=req.size, landscape=req.landscape,
                               custom_mm=req.custom)
