"""Where `rh-generate` renders frames: `LocalBackend` (this machine, worker processes) and `RayBackend` (Ray tasks
on a cluster). Each holds its own settings and is handed to `rh_dataset.generate.generate`; both render every
frame through `rh_dataset.generate.frames.render_frame_to_disk`."""
from rh_dataset.backends.local import LocalBackend
from rh_dataset.backends.ray_backend import RayBackend

__all__ = ["LocalBackend", "RayBackend"]
