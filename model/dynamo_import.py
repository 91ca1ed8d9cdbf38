"""An optimizer without torch._dynamo: what a worker process's first L-BFGS imported.

torch.optim.Optimizer wraps add_param_group and zero_grad (and its state's dict and load) in
torch._disable_dynamo, which imports torch._dynamo at their first call to wrap each in
torch._dynamo.disable: 1.2-1.3 CPU s at a process's first retrain fit, which every worker pays
(two workers: twice).  That wrapper matters only while torch.compile traces, which nothing
here does, so each method is given itself as the disabled form the wrapper caches (the
attribute it looks for before importing).  Where torch._dynamo is already imported or torch
names these otherwise, this leaves them alone: the import then costs what it did."""

from __future__ import annotations

import sys

import torch

# what torch._disable_dynamo caches the disabled form of a function under, on the function
_CACHED = "__dynamo_disable"
_WRAPPED = ("add_param_group", "zero_grad", "state_dict", "load_state_dict")


def skip_dynamo_import() -> None:
    """Let torch.optim's optimizers run without importing torch._dynamo (module docstring);
    idempotent, and a no-op once it is imported."""
    if "torch._dynamo" in sys.modules:
        return
    for name in _WRAPPED:
        function = getattr(getattr(torch.optim.Optimizer, name, None), "__wrapped__", None)
        if function is not None and not hasattr(function, _CACHED):
            setattr(function, _CACHED, function)
