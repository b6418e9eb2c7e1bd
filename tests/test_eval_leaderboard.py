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
