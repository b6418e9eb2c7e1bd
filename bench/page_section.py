"""A copy of an rh-leaderboard page that shows one picture section's image strips only, for a screenshot.

    python bench/page_section.py BOARD/index.html OUT.html [--split SPLIT]

In: the board's index.html (rh_eval.leaderboard). Out: OUT.html beside it (same folder, so its pictures/ resolve),
with a style that hides everything but the picture section of the test split (or of --split) and, inside it, every
row group after the first (the image rows: ground truth, each method, its error map). The README's board pictures
(leaderboards/small/protocol_*/pictures.png) are headless-Chromium screenshots of such a copy.
"""
from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("page", type=Path, help="the board's index.html")
    p.add_argument("out", type=Path, help="the copy to write (in the same folder as the page)")
    p.add_argument("--split", default=None, help="the split whose pictures to keep (default: the test split)")
    a = p.parse_args()
    html = a.page.read_text(encoding="utf-8")
    sections = re.findall(r'<section class="pics" id="(pictures-\d+)"><h2>([^<]*)</h2>', html)
    want = [sid for sid, title in sections if (", split " not in title if a.split is None
                                               else title.endswith(f", split {a.split}"))]
    if not want:
        print(f"page_section: {a.page}: no picture section for split {a.split or 'test'} "
              f"(sections: {[t for _, t in sections]})", file=sys.stderr)
        return 2
    sid = want[0]
    style = (f"<style>body > *:not(#{sid}) {{display: none !important}} "
             f"#{sid} h3:nth-of-type(n+2), #{sid} h3:nth-of-type(n+2) ~ * {{display: none !important}}</style>")
    if a.out.resolve().parent != a.page.resolve().parent:
        print(f"page_section: {a.out} must be in {a.page.parent} (the page's pictures/ are relative)", file=sys.stderr)
        return 2
    a.out.write_text(html.replace("</head>", style + "</head>", 1), encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
