"""The results side of `rh-leaderboard`: rh-eval result files in; `Entry`s out, checked to be combinable (the
same benchmark split by content identity, protocol and convention), grouped by named convention and by the dataset
split scored (`test`, `olat`, ...: one set of tables each, like conventions) and ranked, with
the columns, best values and formatted cells that both outputs (leaderboard.md and index.html,
`rh_eval.leaderboard`) show.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

from rh_common import layout

__all__ = ["COLUMNS", "FLIP_COLUMNS", "ALIGNED_COLUMNS", "IMAGE_ALIGNED_COLUMNS", "SIDE_BY_SIDE", "Entry",
           "load_results"]

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


def _split(e: Entry) -> str:
    """The dataset split a result scored (results from before `rh-eval --split` scored the test split)."""
    return str(e.result.get("dataset", {}).get("split") or layout.TEST_SPLIT)


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
    key = layout.split_key(str(ref.result["dataset"].get("protocol")), _split(ref))
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
        # Records before the noise tier have no "within_rounding": their tolerance was rounding.
        how = "within rounding" if c.get("within_rounding", True) else "within sampling noise"
        diverged = max([v.get("max_diverged_fraction", 0.0) for v in layers.values()] or [0.0])
        spread = f", up to {100 * diverged:.2f} % of a file's pixels diverged" if diverged else ""
        e.within_tolerance = (f"{e.row_name}: scored on content identity `{b[:16]}…`, which agrees with "
                              f"`{a[:16]}…` only {how} (rh-verify --against: {worst}, 8-bit layers "
                              f"within {levels:g} level{spread}; tolerance {c.get('tolerance')})")
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
    names = [(e.name, _conv_name(e), _split(e)) for e in entries]
    for e in entries:  # two results of the same name in one table: tell them apart by file name
        if names.count((e.name, _conv_name(e), _split(e))) > 1:
            e.display = f"{e.name} ({e.path.name})"
    problems = []
    ref = entries[0]
    first: dict[str, Entry] = {}  # conventions are compared with the first result of the same named convention
    first_of_split: dict[str, Entry] = {}  # a split's identity with the first result that scored that split
    for e in entries:
        first.setdefault(_conv_name(e), e)
        first_of_split.setdefault(_split(e), e)
    for e in entries[1:]:
        a, b = ref.result["dataset"].get("protocol"), e.result["dataset"].get("protocol")
        sref = first_of_split[_split(e)]
        if a != b:
            problems.append(f"{e.path}: protocol {b!r} differs from {ref.path}'s {a!r}")
        elif sref is not e and (why := _same_split(sref, e, comparisons or [])) is not None:
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
    """(label, entries) per named convention and scored split, in order of appearance: each gets its own tables.
    The label is the convention's name for the test split, '<convention>-<split>' for another (an HTML id)."""
    out: dict[str, list[Entry]] = {}
    for e in entries:
        split = _split(e)
        out.setdefault(_conv_name(e) if split == layout.TEST_SPLIT else f"{_conv_name(e)}-{split}", []).append(e)
    return list(out.items())


def _several_splits(entries: list[Entry]) -> bool:
    return len({_split(e) for e in entries}) > 1


def _title(entries: list[Entry]) -> str:
    """The heading of one (convention, split) set of tables: Convention `rana` (, split `olat`)."""
    split = _split(entries[0])
    return f"Convention `{_conv_name(entries[0])}`" + ("" if split == layout.TEST_SPLIT else f", split `{split}`")


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
    ident = (f"{_split(entries[0])} split content identity `{d['content_identity'][:16]}…`" if d.get("content_identity")
             else f"dataset manifest sha256 `{str(d.get('manifest_sha256'))[:16]}…`")
    return (f"Protocol {d.get('protocol')}, {ident}; "
            f"region `{c.get('region')}` over {c.get('background')}, LPIPS backbone `{c.get('backbone')}` (v0.1), "
            f"albedo in {c.get('albedo_space')}, {_ppd_text(entries)}. "
            f"↓ lower is better, ↑ higher is better; **bold** = best complete method; ∞ = identical to the "
            f"ground truth on every frame.")
