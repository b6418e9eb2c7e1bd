"""Harness stand-in: the clients import torchvision.models at module level (through lpips, torchmetrics) but
preprocessing never builds a network; any model constructor fails if called."""


def __getattr__(name):
    if name.startswith("__"):
        raise AttributeError(name)

    def unavailable(*a, **k):
        raise RuntimeError(f"torchvision.models.{name} is not available in the offline CPU harness")
    return unavailable
