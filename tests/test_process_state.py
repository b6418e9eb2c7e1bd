"""Process-wide state: torch's thread count is set for a block and restored; importing our modules changes
neither the environment nor torch's thread count.

In: nothing (a fresh interpreter for the import check). Out: pass or the module and what it changed.
Why: a library function or an import that changes process-wide settings silently changes the numbers of
whatever its caller computes next (torch reductions depend on the thread count).
"""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import torch

from rh_common.threads import torch_threads

ROOT = Path(__file__).resolve().parents[1]


def test_torch_threads_sets_for_the_block_and_restores():
    before = torch.get_num_threads()
    n = 1 if before != 1 else 2
    with torch_threads(n):
        assert torch.get_num_threads() == n
    assert torch.get_num_threads() == before
    with pytest.raises(RuntimeError):
        with torch_threads(n):
            raise RuntimeError("boom")
    assert torch.get_num_threads() == before  # restored on the way out of an exception too


@pytest.mark.parametrize("n", [None, 0])
def test_torch_threads_none_or_zero_leaves_the_count(n):
    before = torch.get_num_threads()
    with torch_threads(n):
        assert torch.get_num_threads() == before
    assert torch.get_num_threads() == before


@pytest.mark.parametrize("n", [-1, 1.5, True, "2"])
def test_torch_threads_refuses_what_is_not_a_count(n):
    with pytest.raises(ValueError):
        with torch_threads(n):
            pass


_IMPORT_ALL = r"""
import importlib, json, os, sys
import torch
packages = sys.argv[1:]
root = os.getcwd()
env0, threads0 = dict(os.environ), torch.get_num_threads()
changed = []
for pkg in packages:
    for dirpath, dirnames, filenames in sorted(os.walk(os.path.join(root, pkg))):
        dirnames.sort()
        for f in sorted(filenames):
            if not f.endswith(".py") or f.startswith("bpy_") or f == "__main__.py":  # bpy_*: inside Blender only
                continue
            rel = os.path.relpath(os.path.join(dirpath, f), root)[:-3].replace(os.sep, ".")
            name = rel[: -len(".__init__")] if rel.endswith(".__init__") else rel
            importlib.import_module(name)
            env = dict(os.environ)
            if env != env0:
                changed.append([name, "environment", sorted(set(env.items()) ^ set(env0.items()))])
                env0 = env
            if torch.get_num_threads() != threads0:
                changed.append([name, "torch threads", [threads0, torch.get_num_threads()]])
                threads0 = torch.get_num_threads()
print(json.dumps(changed))
"""


def test_importing_our_modules_changes_no_process_state():
    out = subprocess.run([sys.executable, "-c", _IMPORT_ALL, "rh_common", "rh_dataset", "rh_eval", "rana", "rh_demo"],
                         cwd=ROOT, capture_output=True, text=True, timeout=300,
                         env={**__import__("os").environ, "PYTHONPATH": str(ROOT)})
    assert out.returncode == 0, out.stderr[-3000:]
    changed = json.loads(out.stdout.strip().splitlines()[-1])
    assert not changed, "importing changed process-wide state:\n  " + "\n  ".join(map(str, changed))


def test_an_evaluator_leaves_torch_threads_as_it_found_them():
    """EvalOptions.threads is the rh-eval command's count (applied around its work by the CLI); constructing an
    Evaluator used to set it for the rest of the process."""
    from rh_eval.evaluate import EvalOptions, Evaluator

    before = torch.get_num_threads()
    Evaluator(EvalOptions(metrics=("psnr",), threads=before + 1, progress=False))
    assert torch.get_num_threads() == before
