import numpy as np
import torch


def to_tensor(pic):
    """torchvision's to_tensor for HWC uint8/float arrays and PIL images: CHW float, uint8 scaled to [0, 1]."""
    a = np.asarray(pic)
    if a.ndim == 2:
        a = a[:, :, None]
    t = torch.from_numpy(np.ascontiguousarray(a.transpose(2, 0, 1)))
    return t.float().div(255) if a.dtype == np.uint8 else t.float()
