"""`rh-leaderboard`: several `rh-eval` result files -> `leaderboard.md` (laid out like the paper's Table 2) and a
self-contained folder: `index.html` (sortable tables, pictures of frames and error maps from the tiles rh-eval wrote
beside each result, copied into `pictures/`: `rh_eval.leaderboard_pictures`; per-subject plots as inline SVG).

Only result files scored on the same benchmark split, protocol and convention are combined (`--allow-mixed`
overrides, with a warning in both outputs). The same split = the same content identity (docs/ARCHITECTURE.md,
"Content identity"), or two identities that an `rh-verify A --against B --record FILE` comparison, given with
`--comparison FILE`, found within tolerance: those rows are marked ≈ and the tables say so. Results of rh-eval
versions that recorded no identity are matched on the manifest sha256 as before. Results under different named
conventions (`rh-eval --convention`) get one set of tables each, and a side-by-side table shows each method under
every convention it was scored with. Rows with `"kind": "bound"` (oracles) are listed in their own table, never
ranked; incomplete submissions in another, never ranked as complete. Bold marks the best complete method per
column.
"""
from __future__ import annotations

import argparse
import html
import io
import json
import math
import sys
from dataclasses import dataclass
from pathlib import Path

from rh_common import layout
from rh_common.imageio import atomic_path
from rh_common.interrupt import add_debug_flag, command, on_stop

__all__ = ["main", "load_results", "build_markdown", "build_html", "COLUMNS", "Entry"]

# (key in "overall", group, label, lower_is_better, decimals)
COLUMNS = [
    ("image_lpips", "Image", "LPIPS", True, 4),
    ("image_dists", "Image", "DISTS", True, 4),
    ("image_ssim", "Image", "SSIM", False, 4),
    ("image_psnr", "Image", "PSNR", False, 2),
    ("normal_deg", "Normal", "degrees", True, 2),
    ("albedo_lpips", "Albedo", "LPIPS", True, 4),
    ("albedo_dists", "Albedo", "DISTS", True, 4),
    ("albedo_ssim", "Albedo", "SSIM", False, 4),
    ("albedo_psnr", "Albedo", "PSNR", False, 2),
]
# FLIP is not in Table 2; shown after it, headed by its pixels per degree, when a result has it.
FLIP_COLUMNS = [
    ("image_flip", "FLIP", "Image", True, 4),
    ("albedo_flip", "FLIP", "Albedo", True, 4),
]
ALIGNED_COLUMNS = [(f"albedo_aligned_{k.split('_', 1)[1]}", "Albedo (scale-aligned)", lab, low, dec)
                   for k, _, lab, low, dec in COLUMNS if k.startswith("albedo_")]
IMAGE_ALIGNED_COLUMNS = [(f"image_aligned_{k.split('_', 1)[1]}", "Image (median-aligned)", lab, low, dec)
                         for k, _, lab, low, dec in COLUMNS if k.startswith("image_")]
_CONSISTENT = ("convention",)


@dataclass
class Entry:
    path: Path
    result: dict
    display: str | None = None
    within_tolerance: str | None = None  # its split's identity differs from the first result's, within tolerance

    @property
    def row_name(self) -> str:
        return self.name + (" ≈" if self.within_tolerance else "")

    @property
    def name(self) -> str:
        if self.display:
            return self.display
        return str(self.result.get("method", {}).get("name", self.path.stem))

    @property
    def label(self) -> str:
        """Name with its standing when it is not a ranked method."""
        return self.name + {"bound": " (bound)", "incomplete": " (incomplete)"}.get(self.group, "")

    @property
    def group(self) -> str:
        if self.result.get("kind") == "bound":
            return "bound"
        return "method" if self.result.get("complete", False) else "incomplete"

    def value(self, key: str):
        """float, +inf (PSNR of identical images), or None (not evaluated)."""
        s = self.result.get("overall", {}).get(key)
        if not s:
            return None
        m = s.get("mean")
        if m == "inf":
            return math.inf
        return float(m) if isinstance(m, (int, float)) else None

    def subject_value(self, subject: str, key: str):
        s = self.result.get("per_subject", {}).get(subject, {}).get("metrics", {}).get(key)
        if not s:
            return None
        m = s.get("mean")
        return math.inf if m == "inf" else (float(m) if isinstance(m, (int, float)) else None)


def _identity(e: Entry) -> str | None:
    return e.result.get("dataset", {}).get("content_identity")


def _same_split(ref: Entry, e: Entry, comparisons: list[dict]) -> str | None:
    """None if `e` was scored on `ref`'s benchmark split (setting `e.within_tolerance` when only a comparison
    record says so), else what differs."""
    a, b = _identity(ref), _identity(e)
    if a is None or b is None:  # a result from before content identities: the manifest bytes decide
        ma, mb = (x.result["dataset"].get("manifest_sha256") for x in (ref, e))
        return None if ma == mb else f"dataset manifest sha256 {mb!r} differs from {ref.path}'s {ma!r}"
    if a == b:
        return None
    key = layout.split_key(str(ref.result["dataset"].get("protocol")), layout.TEST_SPLIT)
    for c in comparisons:
        pair = {((c.get(side) or {}).get("identity") or {}).get("splits", {}).get(key, {}).get("digest")
                for side in ("a", "b")}
        if pair != {a, b}:
            continue
        if not c.get("within_tolerance"):
            return (f"content identity {b[:16]}… differs from {ref.path}'s {a[:16]}…, and rh-verify --against "
                    f"found them NOT the same benchmark ({c['a'].get('root')} vs {c['b'].get('root')})")
        layers = {k: v for k, v in c.get("layers", {}).items() if k.startswith(key + "/")}
        psnrs = [v["min_psnr_db"] for v in layers.values() if not v.get("is_8bit") and v["min_psnr_db"] != "inf"]
        worst = f"lowest layer PSNR {min(psnrs):.1f} dB" if psnrs else "float layers equal"
        levels = max([v["max_abs"] for v in layers.values() if v.get("is_8bit")] or [0])
        e.within_tolerance = (f"{e.row_name}: scored on content identity `{b[:16]}…`, which agrees with "
                              f"`{a[:16]}…` only within tolerance (rh-verify --against: {worst}, 8-bit layers "
                              f"within {levels:g} level; tolerance {c.get('tolerance')})")
        return None
    return (f"content identity {b[:16]}… differs from {ref.path}'s {a[:16]}… (if the datasets agree within "
            f"tolerance, give rh-verify A --against B --record FILE's record as --comparison FILE)")


def load_results(paths: list[Path], *, allow_mixed: bool = False,
                 comparisons: list[dict] | None = None) -> tuple[list[Entry], list[str]]:
    """Read result files; refuse (ValueError) files that are not rh-eval results or that disagree on the benchmark
    split (content identity, unless a `comparisons` record finds the two within tolerance), protocol or
    convention (unless `allow_mixed`, which returns the disagreements as warnings)."""
    entries = []
    for p in paths:
        try:
            r = json.loads(Path(p).read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as exc:
            raise ValueError(f"{p}: cannot read result file ({exc})") from exc
        if not isinstance(r, dict) or r.get("format") != "rh-eval/1":
            raise ValueError(f"{p}: not an rh-eval result (format {r.get('format') if isinstance(r, dict) else None!r})")
        entries.append(Entry(Path(p), r))
    if not entries:
        raise ValueError("no result files given")
    names = [(e.name, _conv_name(e)) for e in entries]
    for e in entries:  # two results of the same name under one convention: tell them apart by file name
        if names.count((e.name, _conv_name(e))) > 1:
            e.display = f"{e.name} ({e.path.name})"
    problems = []
    ref = entries[0]
    first: dict[str, Entry] = {}  # conventions are compared with the first result of the same named convention
    for e in entries:
        first.setdefault(_conv_name(e), e)
    for e in entries[1:]:
        a, b = ref.result["dataset"].get("protocol"), e.result["dataset"].get("protocol")
        if a != b:
            problems.append(f"{e.path}: protocol {b!r} differs from {ref.path}'s {a!r}")
        elif (why := _same_split(ref, e, comparisons or [])) is not None:
            problems.append(f"{e.path}: {why}")
        cref = first[_conv_name(e)]
        if cref is e:
            continue
        ca = {k: v for k, v in _conv_fields(cref).items() if k not in ("align_albedo", "align_image")}
        cb = {k: v for k, v in _conv_fields(e).items() if k not in ("align_albedo", "align_image")}
        if not (_has_flip(cref) and _has_flip(e)):  # pixels per degree only matter where both carry FLIP
            ca.pop("flip_ppd", None)
            cb.pop("flip_ppd", None)
        diff = sorted(k for k in set(ca) | set(cb) if ca.get(k) != cb.get(k))
        if "flip_ppd" in diff:
            problems.append(f"{e.path}: FLIP computed at {_ppd(e)} pixels per degree, {cref.path} at {_ppd(cref)}: "
                            f"their FLIP values are not comparable (rerun rh-eval with the same --flip-ppd)")
            diff.remove("flip_ppd")
        if diff:
            problems.append(f"{e.path}: convention differs from {cref.path}'s in "
                            + ", ".join(f"{k} ({cb.get(k)!r} vs {ca.get(k)!r})" for k in diff))
    if problems and not allow_mixed:
        raise ValueError("results are not comparable (use --allow-mixed to combine anyway):\n  - "
                         + "\n  - ".join(problems))
    return entries, problems


def _conv_name(e: Entry) -> str:
    return str(e.result.get("convention", {}).get("name", "rana"))


def _conv_fields(e: Entry) -> dict:
    """The result's convention with the fields it predates filled in (they were computed with the defaults)."""
    from .conventions import Convention  # light: numpy and the colour transform only
    c = e.result.get("convention", {})
    try:
        return Convention.from_json(c).to_json()
    except (TypeError, ValueError):
        return dict(c)


def _align_text(entries: list[Entry]) -> str:
    ways = {str(e.result.get("convention", {}).get("align_albedo")) for e in entries}
    return "median" if ways == {"median"} else "least-squares" if ways <= {"lsq", "True"} else "least-squares or median"


def _by_convention(entries: list[Entry]) -> list[tuple[str, list[Entry]]]:
    out: dict[str, list[Entry]] = {}
    for e in entries:
        out.setdefault(_conv_name(e), []).append(e)
    return list(out.items())


SIDE_BY_SIDE = ("image_lpips", "image_ssim", "image_psnr", "normal_deg", "albedo_aligned_psnr")


def _side_by_side(convs: list[tuple[str, list[Entry]]]) -> tuple[list[str], list[tuple[str, list[str]]]]:
    """Header cells and (method, cells) rows: each method under every convention, the main columns."""
    labels = {k: f"{g} {lab} {'↓' if low else '↑'}" for k, g, lab, low, _ in COLUMNS + ALIGNED_COLUMNS}
    dec = {k: d for k, *_, d in COLUMNS + ALIGNED_COLUMNS}
    cols = [(name, k) for name, es in convs for k in SIDE_BY_SIDE if any(e.value(k) is not None for e in es)]
    methods = list(dict.fromkeys(e.label for _, es in convs for e in es))
    rows = []
    for m in methods:
        cells = []
        for name, k in cols:
            e = next((x for x in dict(convs)[name] if x.label == m), None)
            v = e.value(k) if e is not None else None
            cells.append("—" if v is None else "∞" if v == math.inf else f"{v:.{dec[k]}f}")
        rows.append((m, cells))
    return [f"{labels[k]} ({name})" for name, k in cols], rows


def _has_flip(e: Entry) -> bool:
    return any(e.value(k) is not None for k, *_ in FLIP_COLUMNS)


def _ppd(e: Entry):
    return e.result.get("convention", {}).get("flip_ppd", e.result.get("flip_ppd"))


def _columns(entries: list[Entry]) -> list[tuple]:
    """Table 2's columns, then FLIP's when any result has it (group label carries the pixels per degree, or
    says they differ: each cell then names its own)."""
    flips = [e for e in entries if _has_flip(e)]
    if not flips:
        return list(COLUMNS)
    ppds = sorted({_ppd(e) for e in flips}, key=str)
    group = f"FLIP (ppd {ppds[0]:.4g})" if len(ppds) == 1 else "FLIP (different ppd per row!)"
    return list(COLUMNS) + [(k, group, lab, low, dec) for k, _, lab, low, dec in FLIP_COLUMNS]


def _cell(e: Entry, key: str, v, dec: int, mixed_ppd: bool) -> str:
    s = _fmt(v, dec)
    if mixed_ppd and v is not None and key.endswith("_flip"):
        s += f" (ppd {_ppd(e):.4g})"
    return s


def _fmt(v, dec: int) -> str:
    if v is None:
        return "—"
    if math.isinf(v):
        return "∞"
    return f"{v:.{dec}f}"


def _best(entries: list[Entry], cols) -> dict[str, float]:
    best = {}
    for key, _, _, low, _ in cols:
        vals = [e.value(key) for e in entries if e.group == "method" and e.value(key) is not None]
        if vals:
            best[key] = min(vals) if low else max(vals)
    return best


def _rank_key(e: Entry):
    v = e.value("image_lpips")
    return (v is None, v if v is not None else 0.0, e.name)


def _groups(entries):
    return [
        ("Methods", "method", sorted([e for e in entries if e.group == "method"], key=_rank_key)),
        ("Bounds (oracles; not ranked)", "bound", sorted([e for e in entries if e.group == "bound"], key=_rank_key)),
        ("Incomplete submissions (not ranked)", "incomplete",
         sorted([e for e in entries if e.group == "incomplete"], key=_rank_key)),
    ]


def _ppd_text(entries: list[Entry]) -> str:
    ppds = sorted({_ppd(e) for e in entries if _has_flip(e)}, key=str) or sorted({_ppd(e) for e in entries}, key=str)
    if len(ppds) == 1 and ppds[0] is not None:
        return f"FLIP at {ppds[0]:.4g} pixels per degree"
    return "FLIP at different pixels per degree (" + ", ".join(str(p) for p in ppds) + "): not comparable"


def _convention_line(entries: list[Entry]) -> str:
    c = entries[0].result.get("convention", {})
    d = entries[0].result.get("dataset", {})
    ident = (f"test split content identity `{d['content_identity'][:16]}…`" if d.get("content_identity")
             else f"dataset manifest sha256 `{str(d.get('manifest_sha256'))[:16]}…`")
    return (f"Protocol {d.get('protocol')}, {ident}; "
            f"region `{c.get('region')}` over {c.get('background')}, LPIPS backbone `{c.get('backbone')}` (v0.1), "
            f"albedo in {c.get('albedo_space')}, {_ppd_text(entries)}. "
            f"↓ lower is better, ↑ higher is better; **bold** = best complete method; ∞ = identical to the "
            f"ground truth on every frame.")


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
    lines = ["# Relighting Humans leaderboard", "",
             f"One set of tables per evaluation convention ({', '.join(f'`{n}`' for n, _ in convs)}): numbers of "
             f"different conventions are not comparable with each other.", ""]
    for w in warnings or []:
        lines.append(f"> **Warning:** {w}")
    if warnings:
        lines.append("")
    for name, es in convs:
        body = _markdown_one(es).split("\n")[2:]  # without the page title
        lines += [f"## Convention `{name}`", ""] + ["#" + x if x.startswith("## ") else x for x in body]
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
        parts.append(f'<p class="note">One set of tables per evaluation convention '
                     f'({e(", ".join(n for n, _ in convs))}): numbers of different conventions are not comparable '
                     f'with each other.</p>')
    if len(convs) == 1:
        parts += _html_one(entries, warnings)
    else:
        parts += [f'<p class="warn">Warning: {e(w)}</p>' for w in warnings or []]
        for name, es in convs:
            parts.append(f'<h2 id="convention-{e(name)}">Convention {e(name)}</h2>')
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
                    "(rh-eval --convention) get their own tables, and a side-by-side table shows each method under "
                    "every convention.")
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
