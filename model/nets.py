"""Small data-driven parts: the scaled MLP inside hybrid cells, and the LSTM/GRU baselines."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence

import torch
from torch import Tensor, nn

ACTIVATIONS: dict[str, Callable[[Tensor], Tensor]] = {
    "tanh": torch.tanh,
    "elu": nn.functional.elu,
    "linear": lambda z: z,
}

# Thesis Table 4.4: hidden layers (units, activation); every MLP ends in Dense(1, linear).
THESIS_MLPS: dict[int, tuple[tuple[int, str], ...]] = {
    1: ((5, "tanh"),),
    2: ((10, "elu"), (5, "elu")),
    3: ((10, "tanh"), (5, "elu")),
    4: ((10, "tanh"), (5, "tanh")),
    5: ((20, "tanh"), (10, "elu"), (5, "elu")),
    6: ((20, "tanh"), (10, "elu"), (5, "tanh")),
    7: ((40, "tanh"), (20, "elu"), (10, "elu"), (5, "tanh")),
}

# Thesis Table 4.3: (stacked layers, units per layer) of the LSTM/GRU baselines.
THESIS_RNNS: tuple[tuple[int, int], ...] = tuple((n, u) for n in (1, 2, 4) for u in (16, 32, 64))


def validate_hidden(hidden: Sequence[tuple[int, str]]) -> tuple[tuple[int, str], ...]:
    """Return `hidden` as a tuple after checking sizes and activation names."""
    if not hidden:
        raise ValueError("hidden must name at least one layer")
    for units, activation in hidden:
        if int(units) < 1:
            raise ValueError(f"hidden layer units must be >= 1, got {units}")
        if activation not in ACTIVATIONS:
            raise ValueError(f"unknown activation {activation!r}; allowed: {sorted(ACTIVATIONS)}")
    return tuple((int(u), str(a)) for u, a in hidden)


class MLP(nn.Module):
    """Dense layers with the given activations, then Dense(1, linear).

    Kept as explicit (linear, activation name) pairs so compiled marches can read the structure.
    """

    def __init__(self, hidden: Sequence[tuple[int, str]], in_features: int = 2) -> None:
        super().__init__()
        self.hidden = validate_hidden(hidden)
        sizes = [in_features, *(u for u, _ in self.hidden), 1]
        self.linears = nn.ModuleList(nn.Linear(a, b) for a, b in itertools.pairwise(sizes))
        self.activations = (*(a for _, a in self.hidden), "linear")
        self.output_starts_at_zero = False

    def forward(self, x: Tensor) -> Tensor:  # (..., in_features) -> (...,)
        for linear, activation in zip(self.linears, self.activations, strict=True):
            x = ACTIVATIONS[activation](linear(x))
        return x.squeeze(-1)

    def zero_output(self) -> None:
        """Make the network output exactly zero (used to start a residual correction at the physics)."""
        last = self.linears[-1]
        assert isinstance(last, nn.Linear)
        nn.init.zeros_(last.weight)
        nn.init.zeros_(last.bias)
        self.output_starts_at_zero = True

    def draw_initial(self, generator: torch.Generator) -> None:
        """The initial weights drawn again from `generator` (nn.Linear's rule, layer by layer:
        the weights torch.manual_seed(s) then construction gave, for a generator seeded with s),
        instead of from torch's process-wide generator, which every thread of the process
        draws from; an output made zero stays zero."""
        for linear in self.linears:
            assert isinstance(linear, nn.Linear)
            nn.init.kaiming_uniform_(linear.weight, a=math.sqrt(5), generator=generator)
            bound = 1 / math.sqrt(linear.in_features)
            nn.init.uniform_(linear.bias, -bound, bound, generator=generator)
        if self.output_starts_at_zero:
            self.zero_output()


class SequenceBaseline(nn.Module):
    """Purely data-driven crack model (thesis Table 4.3): stacked LSTM/GRU over scaled stress ranges.

    Input (batch, flights) of stress range in MPa; output (batch, flights) of crack length in m,
    predicted as initial crack * exp(head(hidden)) so the output stays positive.
    """

    stress_lo: Tensor
    stress_span: Tensor

    def __init__(
        self,
        kind: str,
        layers: int,
        units: int,
        stress_scale_mpa: tuple[float, float],
        initial_crack_m: float,
    ) -> None:
        super().__init__()
        rnn_types: dict[str, type[nn.LSTM] | type[nn.GRU]] = {"lstm": nn.LSTM, "gru": nn.GRU}
        if kind not in rnn_types:
            raise ValueError(f"kind must be 'lstm' or 'gru', got {kind!r}")
        if layers < 1 or units < 1:
            raise ValueError("layers and units must be >= 1")
        self.kind, self.layers, self.units = kind, layers, units
        self.rnn = rnn_types[kind](1, units, num_layers=layers, batch_first=True)
        self.head = nn.Linear(units, 1)
        lo, hi = stress_scale_mpa
        if not hi > lo:
            raise ValueError("stress_scale_mpa must be (low, high) with high > low")
        self.register_buffer("stress_lo", torch.tensor(float(lo)))
        self.register_buffer("stress_span", torch.tensor(float(hi - lo)))
        self.initial_crack_m = initial_crack_m

    def forward(self, stress_range_mpa: Tensor) -> Tensor:  # (batch, flights) -> (batch, flights)
        x = ((stress_range_mpa - self.stress_lo) / self.stress_span).unsqueeze(-1)
        hidden, _ = self.rnn(x)
        return self.initial_crack_m * torch.exp(self.head(hidden).squeeze(-1))
