"""Execution backends for `rh-generate`: the local one lives in rh_dataset.generate; `ray_backend` runs the same
frames as Ray tasks (`--backend ray`)."""

__all__: list[str] = []
