"""rana: the benchmark's bundled methods — RANA (Iqbal et al. 2023) on anny, the SMPL+D baseline, and the
Lambertian-SH oracle bound.

Entry points: `rana` (rana.cli: train, predict, smpld, pretrain, plot, synth), `rana-pretrain` (rana.pretrain),
`rana-oracle` (rana.oracle). Modules: config (validated dataclasses + presets), config_json (configs stored as
JSON with a schema version), config_flags (their --section.field flags), body (anny posing, SMPL+D offsets),
raster (z-buffer and soft silhouette), geometry (offset fit), texture (UV back-projection), texturenet, nets,
model (RanaModel), train (coarse stage + personalization), pretrain, predict, runs (checkpoints, log, pretrained.pt),
synthetic (tiny test datasets). Heavy modules are imported lazily by their users; this package imports nothing.
"""

__all__ = ["__version__"]

__version__ = "0.1.0"
