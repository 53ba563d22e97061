"""python -m world2 OUT [--seed N] [--views K | --fixed] [--size W H] [--declare-lens] ..."""

from __future__ import annotations

import argparse

from .world import Options, make_world, write_dataset


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m world2", description=__doc__)
    p.add_argument("out")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--views", type=int, default=6)
    p.add_argument("--fixed", action="store_true", help="one camera standing still")
    p.add_argument("--fixed-photos", type=int, default=4)
    p.add_argument("--size", type=int, nargs=2, default=(2400, 1800))
    p.add_argument("--declare-lens", action="store_true")
    p.add_argument("--print-rms", type=float, default=0.2)
    p.add_argument("--toner", type=float, default=0.06)
    p.add_argument("--paper-peak", type=float, default=0.1)
    p.add_argument("--backlash", type=float, default=0.1)
    p.add_argument("--pen", type=float, default=1.2)
    p.add_argument("--png", action="store_true")
    a = p.parse_args(argv)
    opt = Options(seed=a.seed, views=a.views, fixed=a.fixed, fixed_photos=a.fixed_photos,
                  size_px=tuple(a.size), declare_lens=a.declare_lens, print_rms_mm=a.print_rms,
                  toner_mm=a.toner, paper_peak_mm=a.paper_peak, backlash2_deg=a.backlash,
                  pen_mm=a.pen, jpeg_quality=None if a.png else 95)
    print(write_dataset(make_world(opt), a.out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
