"""``vision-cal sheet``: the printable calibration sheet (PDF, SVG, PNG) and its sheet.json."""

from __future__ import annotations

from vision_cal.commands import bounded, request

NAME = "sheet"
HELP = ("write the printable calibration sheet (vector PDF at true scale, SVG, optional PNG) "
        "and sheet.json, the session's sheet block")
EXAMPLES = """\
examples:
  vision-cal sheet --size A3 --out sheet/                  A3 landscape, DICT_5X5_100
  vision-cal sheet --size A4 --portrait --dictionary DICT_4X4_50 --out a4/
  vision-cal sheet --custom 500 350 --marker-mm 24 --pitch-mm 90 --png-dpi 254 --out s/
  vision-cal sheet --size A2 --field --out field/          marker field for an arm camera
  vision-cal sheet --size A3 --measured-bar-mm 99.8 100.1 --out sheet/
      after printing: record the two 100 mm bars as measured on the paper
  vision-cal sheet --charuco 5x7 --square-mm 36.195 --marker-mm 18.256 --dictionary DICT_6X6_250 -o b/
      an OpenCV ChArUco board (CharucoBoard((5, 7), 36.195, 18.256, DICT_6X6_250)) for
      `vision-cal handeye PHOTOS/ --robot-poses ... --sheet b/sheet.json`

Print sheet.pdf at 100 % (actual size, no fit-to-page) and measure both bars; paste
sheet.json as the "sheet" block of session.json (vision-cal design does it for you).
"""

def add_arguments(p) -> None:
    page = p.add_argument_group("page")
    page.add_argument("--size", default=None, metavar="A0..A4",
                      help="ISO page size (default A3)")
    page.add_argument("--custom", type=bounded(0, 5000, lo_open=True, unit="mm"), nargs=2,
                      metavar=("W", "H"),
                      help="custom page width and height in mm (instead of --size)")
    o = page.add_mutually_exclusive_group()
    o.add_argument("--landscape", dest="landscape", action="store_const", const=True,
                   default=None, help="wider than high (default for ISO sizes)")
    o.add_argument("--portrait", dest="landscape", action="store_const", const=False,
                   help="higher than wide")
    m = p.add_argument_group("markers")
    m.add_argument("--dictionary", default=None, metavar="DICT",
                   help="OpenCV predefined ArUco dictionary (default DICT_5X5_100; with "
                        "--field DICT_5X5_1000)")
    m.add_argument("--marker-mm", type=bounded(0, 1000, lo_open=True, unit="mm"), metavar="S",
                   help="marker side including its black border (default: about 1/15 of "
                        "the short side)")
    m.add_argument("--pitch-mm", type=bounded(0, 5000, lo_open=True, unit="mm"), metavar="P",
                   help="largest centre spacing of the border markers (default 4 markers)")
    p.add_argument("--field", action="store_true",
                   help="a marker field over the whole page for a camera on the arm (no "
                        "ruled grid; default DICT_5X5_1000, 18 mm markers every 36 mm)")
    c = p.add_argument_group("ChArUco board (for vision-cal handeye PHOTOS/ --robot-poses)")
    c.add_argument("--charuco", metavar="COLSxROWS", default=None,
                   help="an OpenCV ChArUco board of COLS x ROWS squares (with --square-mm, "
                        "--marker-mm and --dictionary): sheet.json describes its markers "
                        "and its chessboard corners")
    c.add_argument("--square-mm", type=bounded(1, 1000, unit="mm"), metavar="S", default=None,
                   help="--charuco: the side of a square (mm)")
    c.add_argument("--legacy-pattern", action="store_true",
                   help="--charuco: OpenCV's pattern before 4.6 (boards with an even number "
                        "of rows; CharucoBoard.setLegacyPattern(True))")
    p.add_argument("--png-dpi", type=bounded(10, 2400, unit="dpi"), metavar="N",
                   help="also write sheet.png at N dpi (254 = 10 px/mm); `vision-cal "
                        "simulate` does not need it (it rebuilds the print from sheet.json)")
    p.add_argument("--measured-bar-mm", nargs=2, metavar=("X", "Y"),
                   type=bounded(50, 200, lo_open=True, hi_open=True, unit="mm"),
                   help="the printed x and y scale bars as measured (mm), recorded in "
                        "sheet.json for the calibration's printer scale")
    p.add_argument("-o", "--out", required=True, metavar="DIR",
                   help="folder for sheet.pdf, sheet.svg, sheet.json (and sheet.png)")


def run(args) -> int:
    # imported here, not at the top: every command module is imported to build the parser,
    # and the action pulls numpy, scipy and OpenCV, which `vision-cal --help` does not need
    from vision_cal.actions.sheet import SheetRequest, sheet

    return sheet(request(args, SheetRequest)).show(quiet=args.quiet)
