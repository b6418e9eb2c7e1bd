"""bench/bench_cloth_pose.py's `seen_around`: which skin points a camera around the subject sees (its `through`
column counts the skin that came out through a garment, and of it what is seen)."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

from bench_cloth_pose import seen_around  # noqa: E402


def test_a_point_on_a_lone_sphere_is_seen_and_one_inside_a_box_is_not():
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.1)
    side = np.array([[0.1, 0.0, 0.0]])  # on the sphere, facing +X: the camera at +X sees it
    below = np.array([[0.0, 0.0, -0.1]])  # facing -Z: every horizontal ray from 2 mm under it passes beside the ball
    top = np.array([[0.0, 0.0, 0.1]])
    assert seen_around(side, side / 0.1, [ball]).tolist() == [True]
    assert seen_around(top, top / 0.1, [ball]).tolist() == [True]
    assert seen_around(below, below / 0.1, [ball]).tolist() == [True]
    # The same points under a closed box around the ball (a garment with no opening): no camera sees them.
    box = trimesh.creation.box(extents=(0.4, 0.4, 0.4))
    pts = np.concatenate([side, top, below])
    assert not seen_around(pts, pts / 0.1, [ball, box]).any()
    # A wall on the +X side only: the point facing +X is still seen, from the cameras at its sides (90 degrees
    # off; the 45-degree rays meet the wall).
    wall = trimesh.creation.box(extents=(0.01, 0.4, 0.4))
    wall.apply_translation([0.2, 0.0, 0.0])
    assert seen_around(side, side / 0.1, [ball, wall]).tolist() == [True]
    assert len(seen_around(np.zeros((0, 3)), np.zeros((0, 3)), [ball])) == 0
