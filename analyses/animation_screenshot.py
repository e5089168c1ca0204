"""README picture: a screenshot of an animation page at given times, in headless Chromium.

Run: python analyses/animation_screenshot.py results/sim/animation.html docs/visual/animation.png --time 12
(several --time values write one PNG each, the time appended to the name).
"""

import argparse
from pathlib import Path

from trunk_drake.visual.browser import open_page


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("page", help="HTML page written by trunk-drake (simulate --html, view)")
    parser.add_argument("png", help="PNG to write")
    parser.add_argument("--time", type=float, action="append", help="animation time, s (default: as loaded)")
    parser.add_argument("--size", default="1000x750", help="viewport WIDTHxHEIGHT in pixels")
    args = parser.parse_args()
    width, height = (int(x) for x in args.size.split("x"))
    out = Path(args.png)
    with open_page(args.page, width, height, animated=args.time is not None) as tab:
        for t in args.time or [None]:
            if t is not None:
                tab.seek(t)
            path = out if t is None or len(args.time) == 1 else out.with_name(f"{out.stem}_{t:g}s{out.suffix}")
            print(tab.screenshot(path))
    if tab.errors:
        raise SystemExit(f"the page logged JavaScript errors: {tab.errors}")


if __name__ == "__main__":
    main()
