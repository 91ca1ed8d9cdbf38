"""A residual kernel with a correction to test: its network starts at exactly zero."""

from __future__ import annotations

import torch

from model.hybrid import CrackGrowthModel


def give_correction(model: CrackGrowthModel) -> None:
    """The residual network's output layer drawn (sd 0.3, from torch's generator as the test
    seeded it) and lifted by 0.1, so that the correction and its gradient are not zero."""
    last = model.kernel.mlp.linears[-1]
    assert isinstance(last, torch.nn.Linear)
    with torch.no_grad():
        last.weight.normal_(std=0.3)
        last.bias.fill_(0.1)
