"""One flat vector for a list of tensors, and back: how posteriors and compiled code see weights."""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import Tensor


def flatten(tensors: Sequence[Tensor]) -> Tensor:
    """The tensors' values (detached, float64) in order, as one vector (sum of numels,)."""
    if not tensors:
        return torch.zeros(0, dtype=torch.float64)
    return torch.cat([t.detach().reshape(-1).to(torch.float64) for t in tensors])


def unflatten(flat: Tensor, like: Sequence[Tensor]) -> list[Tensor]:
    """Cut `flat` into tensors shaped like `like` (views, in order).  Raises ValueError when the
    sizes do not add up."""
    total = sum(t.numel() for t in like)
    if flat.shape != (total,):
        raise ValueError(f"flat must be ({total},), got {tuple(flat.shape)}")
    out, offset = [], 0
    for t in like:
        out.append(flat[offset : offset + t.numel()].reshape(t.shape))
        offset += t.numel()
    return out
