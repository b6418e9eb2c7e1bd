"""Pieces every part of the toolkit shares: image I/O, colour conventions, spherical harmonics, dataset layout."""
