"""The leaderboard's pictures: rows of ground truth, each method's frames and error maps, from the tiles `rh-eval`
wrote beside each result (`<result stem>.thumbs/`, `rh_eval.thumbnails`); neither the dataset nor the predictions
are read.

In:  the leaderboard's entries in their display order (ranked methods, bounds, incomplete).
Out: `Pictures`: an HTML section per protocol and scored split (strips + a click-to-enlarge viewer with the frame's name, light
     and per-frame scores) and the tile files to copy into `<out>/pictures/`, so the page stays one folder.

Which frames (docs/EVALUATION.md, "Pictures"): only frames every shown result has tiles for (the seeded fixed
frames are common to all). Among those: the best, median and worst frame of the first-ranked method by its
headline metric, then the fixed frames in their seeded order, at most `max_fixed` of them.
"""
from __future__ import annotations

import html
import json
import math
import re
import shutil
from dataclasses import dataclass, field
from pathlib import Path

from rh_common.imageio import atomic_dir, atomic_path

from .thumbnails import THUMBS_FORMAT, select_extremes

__all__ = ["Pictures", "build_pictures", "write_pictures", "PICTURES_DIR", "PICTURES_CSS", "PICTURES_JS"]

PICTURES_DIR = "pictures"
_TILE = re.compile(r"^[A-Za-z0-9_.-]+/[A-Za-z0-9_.-]+\.webp$")
_ROLE_ORDER = ("best", "median", "worst")
# (layer, title, error label)
_LAYERS = (("image", "Image", "FLIP error"), ("albedo", "Albedo", "FLIP error"), ("normal", "Normal", "angle error"))


@dataclass
class Pictures:
    html: str = ""
    copies: list[tuple[Path, str]] = field(default_factory=list)  # (source tile, path under <out>/pictures/)
    notes: list[str] = field(default_factory=list)


def _load(entry) -> tuple[dict | None, str | None]:
    """The entry's thumbnail index with every tile path checked (inside its folder, a plain name), or a note."""
    rec = entry.result.get("thumbnails")
    if not isinstance(rec, dict):
        return None, None
    d = rec.get("dir")
    if not isinstance(d, str) or "/" in d or "\\" in d or d in ("", ".", ".."):
        return None, f"{entry.path}: thumbnails folder {d!r} is not a plain name beside it; pictures left out"
    folder = entry.path.parent / d
    try:
        index = json.loads((folder / "index.json").read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        return None, f"{folder}/index.json: cannot read ({exc}); rerun rh-eval to rewrite it; pictures left out"
    if not isinstance(index, dict) or index.get("format") != THUMBS_FORMAT or not isinstance(index.get("frames"),
                                                                                              list):
        return None, f"{folder}/index.json: not an {THUMBS_FORMAT} index; pictures left out"
    frames = {}
    for f in index["frames"]:
        tiles = f.get("tiles", {}) if isinstance(f, dict) else {}
        ok = isinstance(f, dict) and isinstance(f.get("name"), str) and isinstance(tiles, dict) and all(
            isinstance(t, str) and _TILE.match(t) and ".." not in t and (folder / t).is_file()
            for t in tiles.values())
        if not ok:
            return None, f"{folder}/index.json: frame entry {str(f)[:80]!r} names a missing or unsafe tile; " \
                         f"rerun rh-eval; pictures left out"
        frames[f["name"]] = dict(f, tiles={k: folder / t for k, t in tiles.items()})
    return {"frames": frames, "selection": index.get("selection", {})}, None


def _num(v):
    return math.inf if v == "inf" else v


def _columns(leader: dict, common: list[str], max_fixed: int) -> list[tuple[str, list[str]]]:
    """[(frame name, roles shown)]: the leader's best/median/worst among `common`, then its fixed frames."""
    head = leader["selection"].get("headline")
    frames = leader["frames"]
    picked: dict[str, list[str]] = {}
    if head:
        rows = [{head: _num(frames[n]["scores"].get(head))} for n in common]
        for role, name in select_extremes(rows, common, [head]).items():
            picked.setdefault(name, []).append(role)
    fixed = sorted((n for n in common if "fixed" in frames[n].get("roles", ())),
                   key=lambda n: str(frames[n].get("seeded_rank", "")))
    for n in fixed[:max_fixed]:
        picked.setdefault(n, []).append("fixed")
    first = [n for r in _ROLE_ORDER for n, rs in picked.items() if rs and rs[0] == r]
    rest = [n for n in picked if n not in first]
    return [(n, picked[n]) for n in dict.fromkeys(first + rest)]


def _protocol_section(pi: int, protocol, shown: list, max_fixed: int, out: Pictures, data: list) -> None:
    e = html.escape
    common = [n for n in shown[0][1]["frames"] if all(n in p["frames"] for _, p in shown)]
    if not common:
        out.notes.append(f"protocol {protocol}: the results have no pictured frame in common; none shown")
        return
    leader = next(((ent, p) for ent, p in shown if ent.group == "method"), shown[0])
    cols = _columns(leader[1], common, max_fixed)
    head = leader[1]["selection"].get("headline")
    methods = [{"label": ent.label, "kind": ent.group} for ent, _ in shown]
    pdata = {"protocol": protocol, "methods": methods, "frames": []}
    for name, roles in cols:
        f0 = leader[1]["frames"][name]
        pdata["frames"].append({"name": name, "roles": roles, "light": f0.get("light", {}),
                                "scores": [p["frames"][name].get("scores", {}) for _, p in shown]})
    data.append(pdata)

    def tile(fi: int, mi: int, layer: str, src: Path, alt: str) -> str:
        rel = f"p{pi}/f{fi}_{'gt' if mi < 0 else f'm{mi}'}_{layer}.webp"
        out.copies.append((src, rel))
        return (f'<td><img class="tile" src="{PICTURES_DIR}/{rel}" alt="{e(alt)}" data-p="{len(data) - 1}" '
                f'data-f="{fi}" data-m="{mi}" data-l="{e(layer)}"></td>')

    lead_name = e(leader[0].label)
    parts = [f'<section class="pics" id="pictures-{pi}"><h2>Pictures: protocol {e(str(protocol))}</h2>',
             f'<p class="note">The evaluated region of each frame as the metrics see it (display space, composited '
             f'over the convention\'s background). Columns: the best, median and worst frame of {lead_name} by '
             f'{e(str(head))} among the frames every result below has pictures of, then fixed frames chosen by a '
             f'seeded rule (docs/EVALUATION.md, Pictures). Error maps: FLIP (0 black to 1 bright) for image and '
             f'albedo, angle between normals (0 to 90 degrees) for normals. Click a picture to enlarge it.</p>']
    header = "<thead><tr><th></th>" + "".join(
        f'<th class="frame">{e(n.split("/")[0])}<br>{e(n.split("/")[-1])}<br>'
        f'<span class="role">{e(" · ".join(r))}</span></th>' for n, r in cols) + "</tr></thead>"
    for layer, title, err_label in _LAYERS:
        have = [(mi, ent, p) for mi, (ent, p) in enumerate(shown)
                if all(layer in p["frames"][n]["tiles"] for n, _ in cols)]
        if not have:
            continue
        gt_src = have[0][2]
        rows = ['<tr class="gt"><th>Ground truth</th>' + "".join(
            tile(fi, -1, layer, gt_src["frames"][n]["tiles"][layer + "_gt"], f"ground truth {layer} {n}")
            for fi, (n, _) in enumerate(cols)) + "</tr>"]
        for mi, ent, p in have:
            cls = "bound" if ent.group == "bound" else ent.group
            badge = '<span class="badge">bound</span>' if ent.group == "bound" else ""
            rows.append(f'<tr class="{cls}"><th>{e(ent.label)}{badge}</th>' + "".join(
                tile(fi, mi, layer, p["frames"][n]["tiles"][layer], f"{ent.label} {layer} {n}")
                for fi, (n, _) in enumerate(cols)) + "</tr>")
            rows.append(f'<tr class="{cls} err"><th>{e(ent.label)}{badge}<br><small>{e(err_label)}</small></th>'
                        + "".join(tile(fi, mi, layer + "_err", p["frames"][n]["tiles"][layer + "_err"],
                                       f"{ent.label} {layer} {err_label} {n}")
                                  for fi, (n, _) in enumerate(cols)) + "</tr>")
        parts.append(f'<h3>{e(title)}</h3><table class="strip">{header}<tbody>' + "".join(rows) + "</tbody></table>")
    parts.append("</section>")
    out.html += "\n".join(parts) + "\n"


def build_pictures(entries: list, max_fixed: int = 6) -> Pictures:
    """The pictures section for `entries` (display order), one per protocol and split (frames of the test and the
    olat split share names, never pictures); empty when no result has tiles."""
    out = Pictures()
    if max_fixed < 0:
        raise ValueError(f"max_fixed must be >= 0, got {max_fixed}")
    by_protocol: dict = {}
    missing = []
    for ent in entries:
        pics, note = _load(ent)
        if note:
            out.notes.append(note)
        if pics is None:
            missing.append(ent.label)
            continue
        d = ent.result.get("dataset", {})
        split = d.get("split") or "test"
        key = d.get("protocol") if split == "test" else f"{d.get('protocol')}, split {split}"
        by_protocol.setdefault(key, []).append((ent, pics))
    data: list = []
    for pi, (protocol, shown) in enumerate(by_protocol.items()):
        _protocol_section(pi, protocol, shown, max_fixed, out, data)
    if not out.html:
        return out
    if missing:
        out.notes.append("no pictures for " + ", ".join(missing) + " (evaluated with --no-thumbnails or by an "
                         "older rh-eval: rerun rh-eval to add them)")
    blob = json.dumps(data, sort_keys=True, allow_nan=False)
    blob = blob.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")  # safe inside <script>
    out.html += (f'<script type="application/json" id="pictures-data">{blob}</script>\n'
                 '<div id="lightbox" hidden><figure><img id="lightbox-img" alt=""><figcaption>'
                 '<div id="lightbox-title"></div><div id="lightbox-light"></div><table id="lightbox-scores">'
                 '</table><div class="note">Click anywhere or press Escape to close.</div></figcaption></figure>'
                 '</div>\n')
    return out


def write_pictures(out_dir: Path, pictures: Pictures) -> int:
    """Copy the tiles into `<out_dir>/pictures/`, replacing that folder whole (`atomic_dir`);
    returns the bytes copied. No tiles: the folder is removed (a stale one would mislead)."""
    dst = Path(out_dir) / PICTURES_DIR
    if not pictures.copies:
        shutil.rmtree(dst, ignore_errors=True)
        return 0
    total = 0
    with atomic_dir(dst) as tmp:
        for src, rel in pictures.copies:
            data = src.read_bytes()
            with atomic_path(tmp / rel) as t:
                t.write_bytes(data)
            total += len(data)
    return total


PICTURES_CSS = """
.pics table.strip{border-collapse:separate;border-spacing:3px;margin:.3em 0 1.2em 0}
.pics table.strip td{border:0;padding:0;text-align:center;vertical-align:middle}
.pics table.strip th{background:none;border:0;cursor:default;font-weight:normal;font-size:.85em;padding:0 .5em 0 0;
  text-align:right;max-width:12em;overflow-wrap:anywhere}
.pics table.strip th.frame{text-align:center;font-size:.75em;color:#444;padding:0 .5em .2em .5em}
.pics .role{font-weight:bold;color:#225}
.pics img.tile{display:block;max-width:128px;max-height:128px;cursor:zoom-in;border:1px solid #ddd}
.pics tr.gt th{font-weight:bold}
.pics tr.err th{color:#666} .pics tr.err td{padding-bottom:6px} .pics tr.bound img.tile{border:2px dashed #b60}
.pics tr.bound th{font-style:italic;color:#555} .pics .badge{display:inline-block;margin-left:.4em;padding:0 .35em;
  font-size:.75em;font-style:normal;border:1px solid #b60;color:#b60;border-radius:3px}
#lightbox{position:fixed;inset:0;background:rgba(0,0,0,.85);display:flex;align-items:center;justify-content:center;
  z-index:10;cursor:zoom-out} #lightbox[hidden]{display:none}
#lightbox figure{margin:0;display:flex;gap:1.5em;align-items:flex-start;color:#eee}
#lightbox img{height:min(75vh,448px);image-rendering:auto;background:#fff}
#lightbox figcaption{max-width:40em;font-size:.9em;background:#222;padding:.8em;border-radius:4px} #lightbox-title{font-size:1.1em;font-weight:bold}
#lightbox table{margin:.6em 0}
#lightbox table td,#lightbox table th{border:1px solid #555;color:#eee;background:none;padding:.15em .5em;cursor:inherit;
  max-width:10em;overflow-wrap:anywhere}
"""

PICTURES_JS = """
(function () {
  const blob = document.getElementById('pictures-data');
  const data = blob ? JSON.parse(blob.textContent) : [];
  const box = document.getElementById('lightbox');
  function fmt(v) { return typeof v === 'number' ? (Math.abs(v) >= 100 ? v.toFixed(2) : v.toPrecision(4)) :
                                                   (v === null || v === undefined ? '—' : (v === 'inf' ? '∞' : String(v))); }
  function show(img) {
    const p = data[+img.dataset.p], f = p.frames[+img.dataset.f], m = +img.dataset.m;
    document.getElementById('lightbox-img').src = img.src;
    const who = m < 0 ? 'ground truth' : p.methods[m].label;
    document.getElementById('lightbox-title').textContent =
      f.name + ' — ' + who + ' — ' + img.dataset.l + ' (' + f.roles.join(', ') + '; protocol ' + p.protocol + ')';
    const light = Object.entries(f.light || {}).map(([k, v]) => k + ' ' + fmt(v)).join(', ');
    document.getElementById('lightbox-light').textContent = 'light: ' + (light || 'not recorded');
    const t = document.getElementById('lightbox-scores');
    t.textContent = '';
    const cols = m < 0 ? p.methods.map((x, i) => [x.label, f.scores[i]]) : [[who, f.scores[m]]];
    const keys = Array.from(new Set(cols.flatMap(c => Object.keys(c[1] || {})))).sort();
    const hr = t.insertRow(); hr.insertCell().textContent = 'per-frame score';
    cols.forEach(([label]) => { const c = document.createElement('th'); c.textContent = label; hr.appendChild(c); });
    keys.forEach(k => {  // one row per score, one column per method: long method names wrap, not the table
      const r = t.insertRow(); r.insertCell().textContent = k;
      cols.forEach(([, sc]) => { r.insertCell().textContent = fmt((sc || {})[k]); });
    });
    box.hidden = false;
  }
  document.querySelectorAll('img.tile').forEach(img => img.addEventListener('click', () => show(img)));
  if (box) box.addEventListener('click', () => { box.hidden = true; });
  document.addEventListener('keydown', ev => { if (ev.key === 'Escape' && box) box.hidden = true; });
  // URL hash "#view=<section>.<frame>.<method>.<layer>" opens that picture (links, and the tests' read-back).
  const v = new URLSearchParams(location.hash.slice(1)).get('view');
  if (v) {
    const [p, f, m, l] = v.split('.');
    const img = Array.from(document.querySelectorAll('img.tile')).find(i =>
      i.dataset.p === p && i.dataset.f === f && i.dataset.m === m && i.dataset.l === l);
    if (img) show(img);
  }
  // Every picture loaded? Counted into the DOM (headless Chromium's --dump-dom reads it back in the tests).
  window.addEventListener('load', () => {
    const imgs = Array.from(document.querySelectorAll('img.tile'));
    const ok = imgs.filter(i => i.complete && i.naturalWidth > 0).length;
    const el = document.getElementById('pictures-check');
    if (el) { el.dataset.loaded = ok; el.dataset.total = imgs.length;
              el.textContent = ok + ' of ' + imgs.length + ' pictures loaded'; }
  });
})();
"""
