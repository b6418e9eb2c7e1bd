"""`rh-leaderboard`: several `rh-eval` result files -> `leaderboard.md` (laid out like the paper's Table 2) and a
self-contained folder: `index.html` (sortable tables, pictures of frames and error maps from the tiles rh-eval wrote
beside each result, copied into `pictures/`: `rh_eval.leaderboard_pictures`; per-subject plots as inline SVG).
Reading, checking, grouping and ranking the results is `rh_eval.leaderboard_results`; this module lays them out.

Only result files scored on the same benchmark split, protocol and convention are combined (`--allow-mixed`
overrides, with a warning in both outputs). The same split = the same content identity (docs/ARCHITECTURE.md,
"Content identity"), or two identities that an `rh-verify A --against B --record FILE` comparison, given with
`--comparison FILE`, found within tolerance: those rows are marked ≈ and the tables say so. Results of rh-eval
versions that recorded no identity are matched on the manifest sha256 as before. Results under different named
conventions (`rh-eval --convention`), and results of different dataset splits (`rh-eval --split`: test, olat),
get one set of tables each, and a side-by-side table shows each method under every convention and split it was
scored with. Rows with `"kind": "bound"` (oracles) are listed in their own table, never
ranked; incomplete submissions in another, never ranked as complete. Bold marks the best complete method per
column.
"""
from __future__ import annotations

import argparse
import html
import io
import math
import sys
from pathlib import Path

from rh_common import layout
from rh_common.imageio import atomic_path
from rh_common.interrupt import add_debug_flag, checkpoint, command, on_stop

from .leaderboard_results import (ALIGNED_COLUMNS, COLUMNS, IMAGE_ALIGNED_COLUMNS, Entry, _align_text, _best,
                                  _by_convention, _cell, _columns, _conv_name, _convention_line, _groups,
                                  _several_splits, _side_by_side, _title, load_results)

__all__ = ["main", "load_results", "build_markdown", "build_html", "COLUMNS", "Entry"]


def _md_table(rows: list[Entry], cols, best, mixed: bool = False, mixed_ppd: bool = False) -> list[str]:
    head = "| Method | " + " | ".join(f"{g} {lab} {'↓' if low else '↑'}" for _, g, lab, low, _ in cols) + " | Frames |"
    sep = "|---|" + "---:|" * len(cols) + "---:|"
    out = [head, sep]
    for e in rows:
        cells = []
        for key, _, _, _, dec in cols:
            v = e.value(key)
            s = _cell(e, key, v, dec, mixed_ppd)
            if e.group == "method" and v is not None and key in best and v == best[key]:
                s = f"**{s}**"
            cells.append(s)
        n = e.result.get("n_frames_evaluated")
        tot = e.result.get("dataset", {}).get("n_frames")
        name = e.label + (" ≈" if e.within_tolerance else "") if mixed else e.row_name
        out.append(f"| {name} | " + " | ".join(cells) + f" | {n}/{tot} |")
    return out


def build_markdown(entries: list[Entry], warnings: list[str] | None = None) -> str:
    convs = _by_convention(entries)
    if len(convs) == 1:
        return _markdown_one(entries, warnings)
    what = "evaluation convention and dataset split" if _several_splits(entries) else "evaluation convention"
    lines = ["# Relighting Humans leaderboard", "",
             f"One set of tables per {what} ({', '.join(f'`{n}`' for n, _ in convs)}): numbers of "
             f"different {_differ(entries)} are not comparable with each other.", ""]
    for w in warnings or []:
        lines.append(f"> **Warning:** {w}")
    if warnings:
        lines.append("")
    for name, es in convs:
        body = _markdown_one(es).split("\n")[2:]  # without the page title
        lines += [f"## {_title(es)}", ""] + ["#" + x if x.startswith("## ") else x for x in body]
    head, rows = _side_by_side(convs)
    lines += ["## Side by side", "", "| Method | " + " | ".join(head) + " |", "|---|" + "---:|" * len(head)]
    lines += [f"| {m} | " + " | ".join(cells) + " |" for m, cells in rows] + [""]
    return "\n".join(lines)


def _markdown_one(entries: list[Entry], warnings: list[str] | None = None) -> str:
    cols = _columns(entries)
    mixed_ppd = any(g.startswith("FLIP (different") for _, g, *_ in cols)
    best = _best(entries, cols) if not mixed_ppd else _best(entries, COLUMNS)
    lines = ["# Relighting Humans leaderboard", "", _convention_line(entries), ""]
    lines += [f"> ≈ {x.within_tolerance}" for x in entries if x.within_tolerance]
    if any(x.within_tolerance for x in entries):
        lines.append("")
    for w in warnings or []:
        lines.append(f"> **Warning:** {w}")
    if warnings:
        lines.append("")
    any_aligned = any(e.value(k) is not None for e in entries for k, *_ in ALIGNED_COLUMNS)
    for title, _, rows in _groups(entries):
        if not rows:
            continue
        lines += [f"## {title}", ""] + _md_table(rows, cols, best, mixed_ppd=mixed_ppd) + [""]
    if any_aligned:
        best_a = _best(entries, ALIGNED_COLUMNS)
        rows = [e for _, _, rs in _groups(entries) for e in rs if any(e.value(k) is not None
                                                                       for k, *_ in ALIGNED_COLUMNS)]
        lines += [f"## Albedo after per-channel {_align_text(entries)} scale (reported separately from the raw "
                  f"scores)", ""]
        lines += _md_table(rows, ALIGNED_COLUMNS, best_a, mixed=True) + [""]
    rows = [e for _, _, rs in _groups(entries) for e in rs if any(e.value(k) is not None
                                                                   for k, *_ in IMAGE_ALIGNED_COLUMNS)]
    if rows:  # --align-image (relightableavatar)
        lines += ["## Relit images after per-channel median scale (reported separately from the raw scores)", ""]
        lines += _md_table(rows, IMAGE_ALIGNED_COLUMNS, _best(entries, IMAGE_ALIGNED_COLUMNS), mixed=True) + [""]
    return "\n".join(lines)


# --------------------------------------------------------------------------------------------- HTML
_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:2em;color:#222;max-width:1400px}
h1{font-size:1.6em} h2{font-size:1.2em;margin-top:1.6em}
table{border-collapse:collapse;margin:.5em 0 1em 0;font-variant-numeric:tabular-nums}
th,td{border:1px solid #ccc;padding:.3em .6em;text-align:right} td:first-child,th:first-child{text-align:left}
th{background:#f0f0f4;cursor:pointer;user-select:none} th.group{cursor:default;text-align:center;background:#e4e4ec}
th.sorted-asc::after{content:" ▲"} th.sorted-desc::after{content:" ▼"}
td.best{font-weight:bold;background:#eaf6ea} tr.bound td{color:#555;font-style:italic}
.note{color:#555;font-size:.9em} .warn{color:#a00} .plots{display:flex;flex-wrap:wrap;gap:1em}
.plots figure{margin:0} .plots figcaption{font-size:.9em;color:#444}
"""

_JS = """
function sortTable(table, col, dir) {
  const tbody = table.tBodies[0];
  const rows = Array.from(tbody.rows);
  const val = r => { const v = r.cells[col].dataset.value; return v === undefined ? r.cells[col].textContent : v; };
  const num = s => (s === 'inf' ? Infinity : (s === '' ? NaN : parseFloat(s)));
  rows.sort((a, b) => {
    const x = num(val(a)), y = num(val(b));
    if (isNaN(x) && isNaN(y)) return val(a).localeCompare(val(b)) * dir;
    if (isNaN(x)) return 1; if (isNaN(y)) return -1;
    return (x < y ? -1 : x > y ? 1 : 0) * dir;
  });
  rows.forEach(r => tbody.appendChild(r));
  table.querySelectorAll('th[data-col]').forEach(th => th.classList.remove('sorted-asc', 'sorted-desc'));
  const th = table.querySelector('th[data-col="' + col + '"]');
  if (th) th.classList.add(dir > 0 ? 'sorted-asc' : 'sorted-desc');
  table.dataset.sortCol = col; table.dataset.sortDir = dir;
}
document.querySelectorAll('table.sortable').forEach(table => {
  table.querySelectorAll('th[data-col]').forEach(th => th.addEventListener('click', () => {
    const col = +th.dataset.col;
    const dir = (+table.dataset.sortCol === col) ? -(+table.dataset.sortDir || 1) : (+th.dataset.default || 1);
    sortTable(table, col, dir);
  }));
});
// URL hash "#sort=<metric key>&dir=asc|desc" sorts every table on load (used by the tests and for links).
(function () {
  const h = new URLSearchParams(location.hash.slice(1));
  const key = h.get('sort'); if (!key) return;
  const dir = h.get('dir') === 'desc' ? -1 : 1;
  document.querySelectorAll('table.sortable').forEach(table => {
    const th = table.querySelector('th[data-key="' + key + '"]');
    if (th) sortTable(table, +th.dataset.col, dir);
  });
})();
"""


def _html_table(rows: list[Entry], cols, best, table_id: str, mixed_ppd: bool = False) -> str:
    e = html.escape
    groups: list[tuple[str, int]] = []
    for _, g, *_ in cols:
        if groups and groups[-1][0] == g:
            groups[-1] = (g, groups[-1][1] + 1)
        else:
            groups.append((g, 1))
    out = [f'<table class="sortable" id="{table_id}"><thead>',
           '<tr><th class="group"></th>' + "".join(f'<th class="group" colspan="{n}">{e(g)}</th>' for g, n in groups)
           + '<th class="group"></th></tr><tr>',
           '<th data-col="0" data-key="name" data-default="1">Method</th>']
    for i, (key, _, lab, low, _) in enumerate(cols, start=1):
        out.append(f'<th data-col="{i}" data-key="{key}" data-default="{1 if low else -1}" '
                   f'title="{"lower" if low else "higher"} is better">{e(lab)} {"↓" if low else "↑"}</th>')
    out.append(f'<th data-col="{len(cols) + 1}" data-key="frames" data-default="-1">Frames</th></tr></thead><tbody>')
    for ent in rows:
        cls = ' class="bound"' if ent.group == "bound" else ""
        label = ent.label + (" ≈" if ent.within_tolerance else "")
        cells = [f'<td data-value="{e(label)}">{e(label)}</td>']
        for key, _, _, _, dec in cols:
            v = ent.value(key)
            dv = "" if v is None else ("inf" if math.isinf(v) else repr(v))
            is_best = ent.group == "method" and v is not None and key in best and v == best[key]
            best_attr = ' class="best"' if is_best else ""
            cells.append(f'<td data-value="{dv}"{best_attr}>{e(_cell(ent, key, v, dec, mixed_ppd))}</td>')
        n = ent.result.get("n_frames_evaluated")
        tot = ent.result.get("dataset", {}).get("n_frames")
        cells.append(f'<td data-value="{n}">{n}/{tot}</td>')
        out.append(f"<tr{cls}>" + "".join(cells) + "</tr>")
    out.append("</tbody></table>")
    return "\n".join(out)


def _plots(entries: list[Entry]) -> list[tuple[str, str]]:
    """Per-subject grouped bar charts (inline SVG) for the main metrics of every listed entry."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    subjects = sorted({s for e in entries for s in e.result.get("per_subject", {})})
    palette = plt.get_cmap("tab10")
    colour = {id(e): palette(i % 10) for i, e in enumerate(entries)}  # one colour per entry in every plot
    figs = []
    for key, title in (("image_lpips", "Image LPIPS ↓"), ("image_psnr", "Image PSNR (dB) ↑"),
                       ("normal_deg", "Normal error (degrees) ↓"), ("albedo_lpips", "Albedo LPIPS ↓")):
        series = [(e, [e.subject_value(s, key) for s in subjects]) for e in entries]
        series = [(e, v) for e, v in series if any(x is not None for x in v)]
        if not series or not subjects:
            continue
        fig, ax = plt.subplots(figsize=(max(5.5, 0.9 * len(subjects) + 4.0), 2.8), dpi=96)
        width = 0.8 / len(series)
        x = np.arange(len(subjects))
        finite = [v for _, vs in series for v in vs if v is not None and math.isfinite(v)]
        cap = max(finite) * 1.15 if finite else 1.0
        for i, (e, vs) in enumerate(series):
            ys = [np.nan if v is None else (cap if math.isinf(v) else v) for v in vs]
            bars = ax.bar(x + (i - (len(series) - 1) / 2) * width, ys, width, label=e.label, color=colour[id(e)],
                          hatch="//" if e.group != "method" else None, alpha=0.9)
            for b, v in zip(bars, vs):
                if v is not None and math.isinf(v):
                    ax.annotate("∞", (b.get_x() + b.get_width() / 2, b.get_height()), ha="center", va="bottom",
                                fontsize=8)
        ax.set_xticks(x, subjects, fontsize=8)
        ax.set_title(title, fontsize=10)
        ax.tick_params(axis="y", labelsize=8)
        ax.legend(fontsize=7, frameon=False, loc="upper left", bbox_to_anchor=(1.01, 1.0))
        fig.tight_layout()
        buf = io.StringIO()
        with plt.rc_context({"svg.hashsalt": "rh-leaderboard"}):  # stable ids: same inputs, same page
            fig.savefig(buf, format="svg", metadata={"Date": None})
        plt.close(fig)
        svg = buf.getvalue()
        svg = svg[svg.index("<svg"):]  # drop the XML prolog/doctype for inlining
        figs.append((title, svg))
    return figs


def build_html(entries: list[Entry], warnings: list[str] | None = None, pictures=None) -> str:
    """The page. `pictures`: a `leaderboard_pictures.Pictures` (its HTML goes after the tables; its tiles are
    copied by `main`), or None for none."""
    from .leaderboard_pictures import PICTURES_CSS, PICTURES_JS

    e = html.escape
    convs = _by_convention(entries)
    parts = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
             "<title>Relighting Humans leaderboard</title>", f"<style>{_CSS}{PICTURES_CSS}</style></head><body>",
             "<h1>Relighting Humans leaderboard</h1>"]
    if len(convs) > 1:
        what = "evaluation convention and dataset split" if _several_splits(entries) else "evaluation convention"
        parts.append(f'<p class="note">One set of tables per {what} '
                     f'({e(", ".join(n for n, _ in convs))}): numbers of different {_differ(entries)} are not '
                     f'comparable with each other.</p>')
    if len(convs) == 1:
        parts += _html_one(entries, warnings)
    else:
        parts += [f'<p class="warn">Warning: {e(w)}</p>' for w in warnings or []]
        for name, es in convs:
            parts.append(f'<h2 id="convention-{e(name)}">{e(_title(es).replace("`", ""))}</h2>')
            parts += _html_one(es, prefix=f"{name}-", h="h3")
    if len(convs) > 1:
        head, rows = _side_by_side(convs)
        parts.append('<h2>Side by side</h2><table id="side-by-side"><thead><tr><th>Method</th>'
                     + "".join(f"<th>{e(h)}</th>" for h in head) + "</tr></thead><tbody>")
        parts += [f"<tr><td>{e(m)}</td>" + "".join(f"<td>{e(c)}</td>" for c in cells) + "</tr>" for m, cells in rows]
        parts.append("</tbody></table>")
    if pictures is not None and pictures.html:
        parts.append(pictures.html)
        parts.append('<p class="note" id="pictures-check"></p>')
    for note in (pictures.notes if pictures is not None else []):
        parts.append(f'<p class="warn">Pictures: {e(note)}</p>')
    parts.append("<h2>Result files</h2><ul>")
    for x in entries:
        r = x.result
        ws = ", ".join(f"{k} {v['sha256'][:12]}…" for k, v in sorted(r.get("weights", {}).items()))
        conv = f", convention {e(_conv_name(x))}" if len(convs) > 1 else ""
        parts.append(f"<li><code>{e(x.path.name)}</code>: {e(x.name)} ({e(x.group)}{conv}), "
                     f"{r.get('n_frames_evaluated')} frames; weights {e(ws)}</li>")
    parts.append("</ul>")
    parts.append(f"<script>{_JS}{PICTURES_JS}</script></body></html>")
    return "\n".join(parts) + "\n"


def _differ(entries: list[Entry]) -> str:
    return "conventions or splits" if _several_splits(entries) else "conventions"


def _html_one(entries: list[Entry], warnings: list[str] | None = None, prefix: str = "", h: str = "h2") -> list[str]:
    """One convention's tables and plots (after its note, `warnings`); table ids start with `prefix`."""
    e = html.escape
    cols = _columns(entries)
    mixed_ppd = any(g.startswith("FLIP (different") for _, g, *_ in cols)
    best = _best(entries, cols) if not mixed_ppd else _best(entries, COLUMNS)
    parts = [f'<p class="note">{e(_convention_line(entries)).replace("**bold**", "<b>bold</b>").replace("`", "")}'
             " Click a column header to sort.</p>"]
    parts += [f'<p class="note">≈ {e(x.within_tolerance).replace("`", "")}</p>' for x in entries if x.within_tolerance]
    parts += [f'<p class="warn">Warning: {e(w)}</p>' for w in warnings or []]
    ids = {"method": "methods", "bound": "bounds", "incomplete": "incomplete"}
    for title, group, rows in _groups(entries):
        if rows:
            parts += [f"<{h}>{e(title)}</{h}>", _html_table(rows, cols, best, prefix + ids[group], mixed_ppd)]
    aligned_rows = [x for _, _, rs in _groups(entries) for x in rs
                    if any(x.value(k) is not None for k, *_ in ALIGNED_COLUMNS)]
    if aligned_rows:
        parts += [f"<{h}>Albedo after per-channel {_align_text(entries)} scale (separate from the raw scores)</{h}>",
                  _html_table(aligned_rows, ALIGNED_COLUMNS, _best(entries, ALIGNED_COLUMNS), prefix + "aligned")]
    rows = [x for _, _, rs in _groups(entries) for x in rs
            if any(x.value(k) is not None for k, *_ in IMAGE_ALIGNED_COLUMNS)]
    if rows:  # --align-image (relightableavatar)
        parts += [f"<{h}>Relit images after per-channel median scale (separate from the raw scores)</{h}>",
                  _html_table(rows, IMAGE_ALIGNED_COLUMNS, _best(entries, IMAGE_ALIGNED_COLUMNS),
                              prefix + "image-aligned")]
    plots = _plots([x for _, _, rs in _groups(entries) for x in rs])
    if plots:
        parts.append(f"<{h}>Per subject</{h}><div class=\"plots\">")
        for title, svg in plots:
            parts.append(f'<figure aria-label="{e(title)}">{svg}</figure>')
        parts.append("</div>")
    return parts


@command("rh-leaderboard")
def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="rh-leaderboard",
        description="Combine rh-eval result files into leaderboard.md (Table 2 layout: Image LPIPS/DISTS/SSIM/PSNR "
                    "| Normal degrees | Albedo LPIPS/DISTS/SSIM/PSNR, best in bold) and a self-contained "
                    "index.html (sortable tables, per-subject plots). Bounds (kind=bound) and incomplete "
                    "submissions are listed separately, never ranked. Results under different named conventions "
                    "(rh-eval --convention) or of different dataset splits (rh-eval --split) get their own tables, "
                    "and a side-by-side table shows each method under every convention and split.")
    p.add_argument("results", nargs="+", type=Path, help="rh-eval result JSON files")
    p.add_argument("--out", type=Path, required=True, help="output folder (index.html, leaderboard.md)")
    p.add_argument("--pictures", type=int, default=6, metavar="N",
                   help="fixed frames per protocol shown as pictures after the first-ranked method's best, median "
                        "and worst (default 6; 0: those three only); tiles come from each result's .thumbs/ "
                        "folder and are copied into OUT/pictures/")
    p.add_argument("--no-pictures", action="store_true", help="no pictures section (and no OUT/pictures/)")
    p.add_argument("--allow-mixed", action="store_true",
                   help="combine results computed on different datasets/protocols/conventions (warned in output)")
    p.add_argument("--comparison", type=Path, action="append", default=[], metavar="FILE",
                   help="a record of `rh-verify A --against B --record FILE`: results scored on A and on B are "
                        "combined if it found them the same benchmark within tolerance (rows marked ≈); repeatable")
    add_debug_flag(p)
    args = p.parse_args(argv)
    on_stop(lambda: f"the tables in {args.out} are each whole (old or new)")
    try:
        comparisons = [layout.read_comparison(c) for c in args.comparison]
        entries, warnings = load_results(args.results, allow_mixed=args.allow_mixed, comparisons=comparisons)
    except (ValueError, OSError) as exc:
        checkpoint()  # an error that follows a stop lost in a C callback is that stop (rh_common.interrupt)
        print(f"rh-leaderboard: error: {exc}", file=sys.stderr)
        return 2
    if args.pictures < 0:
        print(f"rh-leaderboard: error: --pictures must be >= 0, got {args.pictures}", file=sys.stderr)
        return 2
    from .leaderboard_pictures import Pictures, build_pictures, write_pictures

    pictures = Pictures() if args.no_pictures else \
        build_pictures([x for _, _, rs in _groups(entries) for x in rs], args.pictures)
    args.out.mkdir(parents=True, exist_ok=True)
    write_pictures(args.out, pictures)  # first: the page names its tiles only once they are in place
    for name, text in (("leaderboard.md", build_markdown(entries, warnings)),
                       ("index.html", build_html(entries, warnings, pictures))):
        with atomic_path(args.out / name) as tmp:
            tmp.write_text(text, encoding="utf-8")
    print(f"rh-leaderboard: {len(entries)} result(s) -> {args.out / 'index.html'}, {args.out / 'leaderboard.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
