"""torch's intra-op thread count, set for a block and restored after it.

In: a thread count (None or 0: leave torch's count as it is). Out: a context manager.
Why one helper: torch's thread count is process-global, and some results depend on it (anny's blendshape and
skinning reductions sum in a thread-count-dependent order, which moves the last digit of vertices and bone poses).
A library function that set it and returned would change every later computation of its caller; so it is set
only here, around the work or at a command's entry, and restored on the way out, also on an exception.
"""
from __future__ import annotations

import contextlib
from collections.abc import Iterator

__all__ = ["torch_threads"]


@contextlib.contextmanager
def torch_threads(n: int | None) -> Iterator[None]:
    """Run the block with `n` torch intra-op threads (None or 0: unchanged), then restore the previous count."""
    if n is not None and (isinstance(n, bool) or not isinstance(n, int) or n < 0):
        raise ValueError(f"torch_threads: a thread count must be an int >= 0 (0 or None: unchanged), got {n!r}")
    if not n:
        yield
        return
    import torch  # heavy: only when a count is set

    before = torch.get_num_threads()
    torch.set_num_threads(n)
    try:
        yield
    finally:
        torch.set_num_threads(before)
