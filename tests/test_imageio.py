"""rh_common.imageio: files written atomically get the mode a plain open() gives (0666 less the umask), not
mkstemp's 0600, and the folders made on the way mkdir's (0777 less the umask), so a dataset on a shared filesystem
is readable by the group the umask allows."""
import os
import stat

import numpy as np
import pytest

from rh_common.imageio import atomic_dir, atomic_path, write_exr, write_json, write_png, write_webp


@pytest.mark.parametrize("umask", [0o022, 0o002, 0o077])
def test_atomic_files_follow_the_umask(tmp_path, umask):
    old = os.umask(umask)
    try:
        write_exr(tmp_path / "a.exr", np.zeros((2, 2, 3), np.float32))
        write_png(tmp_path / "a.png", np.zeros((2, 2, 3), np.uint8))
        write_json(tmp_path / "a.json", {"k": 1})
        write_json(tmp_path / "new" / "deeper" / "b.json", {"k": 1})  # folders made on the way
        with atomic_path(tmp_path / "a.bin") as tmp:
            tmp.write_bytes(b"x")
        reference = tmp_path / "plain.bin"
        reference.write_bytes(b"x")  # what open() gives under this umask
        (tmp_path / "plain_dir").mkdir()  # what mkdir gives
    finally:
        os.umask(old)
    want = stat.S_IMODE(reference.stat().st_mode)
    assert want == 0o666 & ~umask
    for name in ("a.exr", "a.png", "a.json", "a.bin", "new/deeper/b.json"):
        assert stat.S_IMODE((tmp_path / name).stat().st_mode) == want, name
    want_dir = stat.S_IMODE((tmp_path / "plain_dir").stat().st_mode)
    assert want_dir == 0o777 & ~umask
    for name in ("new", "new/deeper"):
        assert stat.S_IMODE((tmp_path / name).stat().st_mode) == want_dir, name


def test_atomic_dir_replaces_a_folder_whole(tmp_path):
    dst = tmp_path / "pics"
    with atomic_dir(dst) as d:
        (d / "a.txt").write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_dir(dst) as d:
            (d / "b.txt").write_text("half")
            raise RuntimeError("killed half way")
    assert sorted(p.name for p in dst.iterdir()) == ["a.txt"]  # the failed set left no trace
    with atomic_dir(dst) as d:
        (d / "sub").mkdir()
        write_webp(d / "sub" / "t.webp", np.zeros((4, 6, 3), np.uint8))
    assert sorted(str(p.relative_to(dst)) for p in dst.rglob("*")) == ["sub", "sub/t.webp"]  # old files gone
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pics"]  # no temporary or old folder left
    assert stat.S_IMODE(dst.stat().st_mode) == 0o777 & ~os.umask(os.umask(0o022))
    with pytest.raises(ValueError, match="uint8"):
        write_webp(tmp_path / "x.webp", np.zeros((4, 4, 3), np.float32))
