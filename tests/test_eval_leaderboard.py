"""rh-leaderboard: Table-2 Markdown, bounds and incomplete submissions apart, and the HTML page read back from
headless Chromium after its JavaScript sorted the table."""
from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from rh_eval.cli import main as eval_main
from rh_eval.leaderboard import main as lb_main
from test_eval_fake import make_dataset, make_predictions

CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-background-networking",
                  "--disable-component-update", "--disable-sync"]


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    root = tmp_path_factory.mktemp("lb")
    ds = make_dataset(root / "ds")
    out = root / "results"
    specs = [("good", dict(noise=0.02)), ("okay", dict(noise=0.06, fmt="png")),
             ("imgonly", dict(noise=0.04, layers=("image",))), ("oracle", dict(kind="bound")),
             ("partial", dict(noise=0.01, layers=("image",)))]
    for name, kw in specs:
        pred = make_predictions(ds, root / name, name=name, **kw)
        args = [str(pred), "--dataset", str(ds), "--out", str(out / f"{name}.json"), "--no-progress",
                "--metrics", "lpips,ssim,psnr,normal"]
        if name == "partial":
            (pred / "subject_001/protocol_a/test/frame_000001_image.exr").unlink()
            args.append("--allow-incomplete")
        assert eval_main(args) == 0
    return root, ds, out


def _lb(results, tmp_path, *extra):
    root, ds, out = results
    dst = tmp_path / "leaderboard"
    code = lb_main([str(p) for p in sorted(out.glob("*.json"))] + ["--out", str(dst), *extra])
    return code, dst


def test_markdown_is_laid_out_like_table_2(results, tmp_path):
    code, dst = _lb(results, tmp_path)
    assert code == 0
    md = (dst / "leaderboard.md").read_text()
    header = [l for l in md.splitlines() if l.startswith("| Method")][0]
    cols = [c.strip() for c in header.strip("|").split("|")]
    assert cols[:10] == ["Method", "Image LPIPS ↓", "Image DISTS ↓", "Image SSIM ↑", "Image PSNR ↑",
                         "Normal degrees ↓", "Albedo LPIPS ↓", "Albedo DISTS ↓", "Albedo SSIM ↑", "Albedo PSNR ↑"]
    sections = re.split(r"^## ", md, flags=re.M)
    methods = [s for s in sections if s.startswith("Methods")][0]
    bounds = [s for s in sections if s.startswith("Bounds")][0]
    incomplete = [s for s in sections if s.startswith("Incomplete")][0]
    assert "| oracle |" in bounds and "oracle" not in methods and "∞" in bounds
    assert "| partial |" in incomplete and "partial" not in methods and "3/4" in incomplete
    rows = [l for l in methods.splitlines() if l.startswith("| ") and not l.startswith("| Method")]
    assert [r.split("|")[1].strip() for r in rows] == ["good", "imgonly", "okay"]  # ranked by image LPIPS
    good = rows[0]
    assert good.count("**") >= 2 * 4  # best of the complete methods is bold
    assert "**" not in bounds and "**" not in incomplete  # never ranked


def test_incomparable_results_are_refused(results, tmp_path, capsys):
    root, ds, out = results
    other = tmp_path / "vgg.json"
    res = json.loads((out / "good.json").read_text())
    res["convention"]["backbone"] = "vgg"
    other.write_text(json.dumps(res))
    code = lb_main([str(out / "good.json"), str(other), "--out", str(tmp_path / "x")])
    assert code == 2 and "backbone" in capsys.readouterr().err
    code = lb_main([str(out / "good.json"), str(other), "--out", str(tmp_path / "x"), "--allow-mixed"])
    assert code == 0 and "Warning" in (tmp_path / "x" / "leaderboard.md").read_text()
    bad = tmp_path / "bad.json"
    bad.write_text("{}")
    assert lb_main([str(bad), "--out", str(tmp_path / "y")]) == 2


def _chromium() -> str:
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    assert exe, "Debian chromium is required for this test (setup.sh installs it: apt-get install -y chromium)"
    return exe


def _dump_dom(html_path: Path, fragment: str, tmp_path: Path) -> str:
    proc = subprocess.run([_chromium(), *CHROMIUM_FLAGS, f"--user-data-dir={tmp_path / 'chrome'}",
                           "--virtual-time-budget=2000", "--dump-dom", f"{html_path.as_uri()}{fragment}"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return proc.stdout


def _table_rows(dom: str, table_id: str) -> list[list[str]]:
    m = re.search(rf'<table[^>]*id="{table_id}".*?<tbody>(.*?)</tbody>', dom, flags=re.S)
    assert m, f"table {table_id} not in the DOM"
    rows = re.findall(r"<tr[^>]*>(.*?)</tr>", m.group(1), flags=re.S)
    return [[re.sub(r"<[^>]+>", "", c).strip() for c in re.findall(r"<td[^>]*>(.*?)</td>", r, flags=re.S)]
            for r in rows]


def test_html_table_sorts_in_headless_chromium(results, tmp_path):
    code, dst = _lb(results, tmp_path)
    assert code == 0
    page = dst / "index.html"
    text = page.read_text()
    assert "<svg" in text and not re.search(r'(src|href)\s*=\s*"(https?:)?//', text)  # self-contained
    res = {p.stem: json.loads(p.read_text()) for p in results[2].glob("*.json")}
    psnr = {k: v["overall"]["image_psnr"]["mean"] for k, v in res.items() if k in ("good", "okay", "imgonly")}
    for direction in ("asc", "desc"):
        dom = _dump_dom(page, f"#sort=image_psnr&dir={direction}", tmp_path)
        rows = _table_rows(dom, "methods")
        names = [r[0] for r in rows]
        want = sorted(psnr, key=psnr.get, reverse=(direction == "desc"))
        assert names == want, (direction, names)
        assert f'class="sorted-{direction}"' in dom or f"sorted-{direction}" in dom
        # the read-back numbers are the result files' numbers
        for r in rows:
            assert float(r[4]) == pytest.approx(psnr[r[0]], abs=0.006)
    bounds = _table_rows(_dump_dom(page, "", tmp_path), "bounds")
    assert bounds[0][0] == "oracle (bound)" and bounds[0][4] == "∞"


def test_html_renders_to_a_screenshot(results, tmp_path):
    code, dst = _lb(results, tmp_path)
    shot = tmp_path / "shot.png"
    proc = subprocess.run([_chromium(), *CHROMIUM_FLAGS, f"--user-data-dir={tmp_path / 'chrome'}",
                           "--window-size=1200,1600", f"--screenshot={shot}", (dst / "index.html").as_uri()],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and shot.is_file() and shot.stat().st_size > 20_000, proc.stderr[-2000:]


def _with_flip(src: Path, dst: Path, ppd: float, value: float, name: str) -> Path:
    res = json.loads(src.read_text())
    res["convention"]["flip_ppd"] = res["flip_ppd"] = ppd
    res["overall"]["image_flip"] = {"mean": value, "std": 0.0, "n": 4, "n_undefined": 0}
    res["method"]["name"] = name
    dst.write_text(json.dumps(res))
    return dst


def test_flip_ppd_is_shown_and_never_mixed_silently(results, tmp_path, capsys):
    root, ds, out = results
    a = _with_flip(out / "good.json", tmp_path / "a.json", 67.02064514160156, 0.125, "a")
    b = _with_flip(out / "okay.json", tmp_path / "b.json", 67.02064514160156, 0.25, "b")
    assert lb_main([str(a), str(b), "--out", str(tmp_path / "same")]) == 0
    md = (tmp_path / "same" / "leaderboard.md").read_text()
    assert "FLIP (ppd 67.02) Image ↓" in md and "**0.1250**" in md and "67.02 pixels per degree" in md
    c = _with_flip(out / "okay.json", tmp_path / "c.json", 30.0, 0.05, "c")
    code = lb_main([str(a), str(c), "--out", str(tmp_path / "mixed")])
    err = capsys.readouterr().err
    assert code == 2 and "pixels per degree" in err and "--flip-ppd" in err
    assert lb_main([str(a), str(c), "--out", str(tmp_path / "mixed"), "--allow-mixed"]) == 0
    md = (tmp_path / "mixed" / "leaderboard.md").read_text()
    assert "Warning" in md and "FLIP (different ppd per row!)" in md
    assert "0.1250 (ppd 67.02)" in md and "0.0500 (ppd 30)" in md and "**0.0500" not in md  # never a best
    page = (tmp_path / "mixed" / "index.html").read_text()
    assert "0.0500 (ppd 30)" in page and "not comparable" in page
    # without FLIP values the viewing condition is irrelevant: combined without a word
    res = json.loads((out / "okay.json").read_text())
    res["convention"]["flip_ppd"] = 30.0
    (tmp_path / "d.json").write_text(json.dumps(res))
    assert lb_main([str(out / "good.json"), str(tmp_path / "d.json"), "--out", str(tmp_path / "noflip")]) == 0
    md = (tmp_path / "noflip" / "leaderboard.md").read_text()
    assert "FLIP (" not in md and "Warning" not in md


# ------------------------------------------------------------------------------------------------ pictures
def _check(dom: str) -> tuple[int, int]:
    m = re.search(r'id="pictures-check"[^>]*data-loaded="(\d+)"[^>]*data-total="(\d+)"', dom)
    assert m, "the page's picture check did not run"
    return int(m.group(1)), int(m.group(2))


def test_pictures_load_and_enlarge_in_headless_chromium(results, tmp_path):
    code, dst = _lb(results, tmp_path)
    assert code == 0
    page = (dst / "index.html").read_text()
    srcs = re.findall(r'<img class="tile" src="([^"]+)"', page)
    assert srcs and all(s.startswith("pictures/") and (dst / s).is_file() for s in srcs)  # one folder
    n_frames = 3  # 4 frames, each pictured by every result, but `partial` lacks one: only frames all have
    assert page.count('<th class="frame">') == 3 * n_frames  # image, albedo, normal tables
    # rows: ground truth, then each result and its error map; albedo and normal only for results that have them
    with_albedo = 3  # good, okay, oracle (imgonly and partial have images only)
    assert len(srcs) == n_frames * ((1 + 2 * 5) + 2 * (1 + 2 * with_albedo))
    dom = _dump_dom(dst / "index.html", "#view=0.0.-1.image", tmp_path)
    loaded, total = _check(dom)
    assert loaded == total == len(srcs)
    title = re.search(r'id="lightbox-title">(.*?)</div>', dom).group(1)
    assert title.startswith("subject_") and "ground truth" in title and "protocol a" in title
    scores = re.search(r'id="lightbox-scores">(.*?)</table>', dom, flags=re.S).group(1)
    assert all(n in scores for n in ("good", "okay", "oracle (bound)", "image_psnr", "∞"))
    assert '<tr class="bound"><th>oracle (bound)<span class="badge">bound</span>' in dom  # marked as a bound
    # a broken tile is counted as such
    (dst / srcs[0]).unlink()
    loaded, total = _check(_dump_dom(dst / "index.html", "", tmp_path))
    assert (loaded, total) == (len(srcs) - 1, len(srcs))


def test_hostile_names_and_thumbnail_indexes_stay_harmless(results, tmp_path):
    root, ds, out = results
    src = tmp_path / "src"
    src.mkdir()
    hostile = ['<script>document.title="pwned"</script>', '"><img src=x onerror=alert(1)>', "</script><b>x"]
    paths = []
    for i, name in enumerate(hostile):
        res = json.loads((out / "good.json").read_text())
        res["method"]["name"] = name
        shutil.copytree(out / "good.thumbs", src / "good.thumbs", dirs_exist_ok=True)
        (src / f"h{i}.json").write_text(json.dumps(res))
        paths.append(src / f"h{i}.json")
    evil = json.loads((out / "okay.json").read_text())  # a result whose index points outside its folder
    shutil.copytree(out / "okay.thumbs", src / "evil.thumbs")
    idx = json.loads((src / "evil.thumbs" / "index.json").read_text())
    idx["frames"][0]["tiles"]["image"] = "../../../../etc/passwd"
    (src / "evil.thumbs" / "index.json").write_text(json.dumps(idx))
    evil["thumbnails"]["dir"] = "evil.thumbs"
    evil["method"]["name"] = "evil"
    (src / "evil.json").write_text(json.dumps(evil))
    dst = tmp_path / "lb"
    assert lb_main([str(p) for p in paths] + [str(src / "evil.json"), "--out", str(dst)]) == 0
    page = (dst / "index.html").read_text()
    for name in hostile:
        assert name not in page
    assert "<img src=x" not in page and "<script>document" not in page
    assert "<b>x" not in page and "evil.thumbs/index.json" in page and "unsafe tile" in page
    assert not any("passwd" in p.name for p in dst.rglob("*"))
    dom = _dump_dom(dst / "index.html", "#view=0.0.0.image", tmp_path)
    assert "<title>Relighting Humans leaderboard</title>" in dom and 'src="x"' not in dom
    assert "&lt;img src=x onerror=alert(1)&gt;" in re.search(r'id="lightbox-title">(.*?)</div>', dom).group(1)
    assert _check(dom)[0] == _check(dom)[1] > 0


PAGE_LIMIT_BYTES = 2_500_000  # 10 methods x 2 protocols, 128 px tiles: measured 1.45 MB (docs/EVALUATION.md, "Pictures")


def test_ten_methods_two_protocols_stay_small(tmp_path):
    ds = make_dataset(tmp_path / "ds", size=256, frames=tuple(range(6)))
    pred = make_predictions(ds, tmp_path / "noisy", name="noisy", noise=0.08)
    res_dir = tmp_path / "res"
    assert eval_main([str(pred), "--dataset", str(ds), "--out", str(res_dir / "noisy.json"), "--no-progress",
                      "--metrics", "psnr,ssim,normal"]) == 0
    base = json.loads((res_dir / "noisy.json").read_text())
    paths = []
    for protocol in ("a", "b"):
        for i in range(10):
            stem = f"m{i}_{protocol}"
            res = json.loads(json.dumps(base))
            res["method"]["name"] = f"method {i}"
            res["dataset"]["protocol"] = protocol
            res["thumbnails"]["dir"] = f"{stem}.thumbs"
            shutil.copytree(res_dir / "noisy.thumbs", res_dir / f"{stem}.thumbs")
            (res_dir / f"{stem}.json").write_text(json.dumps(res))
            paths.append(res_dir / f"{stem}.json")
    dst = tmp_path / "lb"
    assert lb_main([str(p) for p in paths] + ["--out", str(dst), "--allow-mixed"]) == 0
    page = (dst / "index.html").read_text()
    assert page.count('<section class="pics"') == 2
    n_tiles = len(re.findall(r'<img class="tile"', page))
    n_cols = page.count('<th class="frame">') // (2 * 3)  # best, median, worst + 6 fixed, fewer where they overlap
    assert 6 <= n_cols <= 9
    assert n_tiles == 2 * n_cols * 3 * (1 + 2 * 10)  # 2 protocols, 3 layers, ground truth + 10 x (frame, error)
    size = sum(p.stat().st_size for p in dst.rglob("*") if p.is_file())
    print(f"10 methods x 2 protocols: {n_tiles} tiles, {size} bytes in all, index.html {len(page.encode())} bytes")
    assert size < PAGE_LIMIT_BYTES
    loaded, total = _check(_dump_dom(dst / "index.html", "", tmp_path))
    assert loaded == total == n_tiles
