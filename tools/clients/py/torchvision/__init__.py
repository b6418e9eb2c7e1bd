"""Harness stand-in for torchvision's CUDA wheel (cannot load beside CPU torch): only what the clients call."""
